"""Layer: history storage. Imports only the codec, the history schema and export, pyarrow and
mcap.

A recording file read back as frames, for replay (``cobot-hmi emulator --replay``): a Parquet
export (or a closed segment) of this project, or an MCAP export (its ``/ROBOT/frames``
channel). The frames come back as their wire bytes, ``(n, 284)``, with their receive times, in
time order. A Parquet file without some element columns (an export of some fields) replays
those elements as zero.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Final

import numpy as np
import numpy.typing as npt
import orjson
import pyarrow as pa
import pyarrow.parquet as pq
from mcap.reader import make_reader

from cobot_hmi.codec import CodecError, encode_frame, frame_from_json
from cobot_hmi.history.export import FRAME_SCHEMA_NAME
from cobot_hmi.history.schema import T2O_SEQUENCE, TIME, U8, raw_from_columns, time_seconds

MCAP_MAGIC: Final = b"\x89MCAP"
PARQUET_MAGIC: Final = b"PAR1"


class RecordingError(ValueError):
    """A file that is not a recording this project can replay, said in words."""


@dataclass(frozen=True, slots=True)
class Recording:
    time_s: npt.NDArray[np.float64]
    raw: U8
    robot: str | None = None

    def __len__(self) -> int:
        return int(self.time_s.size)


def read_recording(path: Path, robot: str | None = None) -> Recording:
    """The frames of a Parquet or MCAP recording; ``RecordingError`` for anything else."""
    try:
        with path.open("rb") as file:
            magic = file.read(5)
    except OSError as error:
        raise RecordingError(f"cannot read {path}: {error.strerror or error}") from None
    if magic.startswith(PARQUET_MAGIC):
        recording = _read_parquet(path)
    elif magic.startswith(MCAP_MAGIC):
        recording = _read_mcap(path, robot)
    else:
        raise RecordingError(f"{path}: neither Parquet nor MCAP (a history export is either)")
    if len(recording) == 0:
        raise RecordingError(f"{path}: no frames")
    order = np.argsort(recording.time_s, kind="stable")
    return Recording(recording.time_s[order], recording.raw[order], recording.robot)


def _read_parquet(path: Path) -> Recording:
    try:
        table = pq.read_table(path)
    except (OSError, pa.ArrowException) as error:
        raise RecordingError(f"{path}: not a readable Parquet file ({error})") from None
    if TIME not in table.schema.names:
        raise RecordingError(f"{path}: no '{TIME}' column (not a history export)")
    metadata = table.schema.metadata or {}
    robot = metadata.get(b"robot")
    return Recording(
        time_seconds(table), raw_from_columns(table), robot.decode() if robot else None
    )


def _read_mcap(path: Path, robot: str | None) -> Recording:
    times: list[float] = []
    rows: list[bytes] = []
    chosen: str | None = None
    try:
        with path.open("rb") as file:
            for schema, channel, message in make_reader(file).iter_messages():
                if schema is None or schema.name != FRAME_SCHEMA_NAME:
                    continue
                topic_robot = channel.topic.strip("/").split("/")[0]
                if chosen is None and (robot is None or topic_robot == robot):
                    chosen = topic_robot
                if topic_robot != chosen:
                    continue
                data = orjson.loads(message.data)
                times.append(float(data.pop("time", message.log_time / 1e9)))
                data.pop("seq", None)
                data.pop(T2O_SEQUENCE, None)
                rows.append(encode_frame(frame_from_json(data))[:284])
    except (OSError, CodecError, orjson.JSONDecodeError, ValueError) as error:
        raise RecordingError(f"{path}: not a readable MCAP recording ({error})") from None
    if chosen is None:
        wanted = f" of robot {robot!r}" if robot else ""
        raise RecordingError(f"{path}: no {FRAME_SCHEMA_NAME} channel{wanted}")
    raw = np.frombuffer(b"".join(rows), dtype=np.uint8).reshape(-1, 284)
    return Recording(np.asarray(times, dtype=np.float64), raw, chosen)

"""Layer: history storage. Imports only the recording's schema and formats, the codec's sizes and
pyarrow/numpy.

The open segment's journal keeps each frame as it came off the wire: ``time``, ``seq``,
``t2o_sequence`` and the 284-byte T→O payload (``t2o_payload``, ``fixed_size_binary(284)``),
``JOURNAL_SCHEMA``. The recorder appends a batch per robot per flush (a second), and slicing
the payloads into the recording's 185 element columns there (``schema.column_arrays``) cost
about a millisecond per batch, most of it building the columns' Arrow arrays one by one: at
16 robots the recorder's thread was the service's third busiest. A batch of the journal's form
costs four columns. The element columns are sliced when the journal is read (a query of the
open segment parses each batch once, ``segments.read_journal``) and when it is closed into a
Parquet segment, a few thousand rows at a time, where the fixed cost per batch is spread over
many frames.

A journal written by an earlier version holds the element columns themselves: readers tell the
two forms apart by the schema (``is_journal_form``) and give both as the recording's schema.
The journal's schema carries its format's version and the layout's (``formats``).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Final

import numpy as np
import pyarrow as pa

from cobot_hmi.codec import T2O_SIZE
from cobot_hmi.history.formats import JOURNAL, version_metadata
from cobot_hmi.history.schema import (
    SCHEMA,
    SEQ,
    T2O_SEQUENCE,
    TIME,
    TIME_TYPE,
    column_arrays,
    time_us,
)

T2O_PAYLOAD: Final = "t2o_payload"
"""The journal's column of T→O payloads, as received (``fixed_size_binary(284)``)."""

PAYLOAD_TYPE: Final = pa.binary(T2O_SIZE)

JOURNAL_SCHEMA: Final = pa.schema(
    [
        SCHEMA.field(TIME),
        SCHEMA.field(SEQ),
        SCHEMA.field(T2O_SEQUENCE),
        pa.field(
            T2O_PAYLOAD,
            PAYLOAD_TYPE,
            nullable=False,
            metadata={"description": "the T→O payload as received (the layout's bytes)"},
        ),
    ],
    metadata={**(SCHEMA.metadata or {}), **version_metadata(JOURNAL)},
)


def is_journal_form(schema: pa.Schema) -> bool:
    """A batch of this schema holds payloads, not element columns."""
    return T2O_PAYLOAD in schema.names


def records_to_journal_batch(
    records: Sequence[tuple[int, float, object, int, bytes]],
) -> pa.RecordBatch:
    """Frame records ``(seq, received_at, frame, t2o_sequence, payload)`` as one batch of the
    journal's form (each payload exactly ``T2O_SIZE`` bytes: the originator refuses others)."""
    n = len(records)
    times = time_us([record[1] for record in records])
    payloads = pa.py_buffer(b"".join([record[4] for record in records]))
    if payloads.size != n * T2O_SIZE:
        raise ValueError(f"{n} payloads of {payloads.size} bytes: each must be {T2O_SIZE}")
    return pa.RecordBatch.from_arrays(
        [
            pa.Array.from_buffers(TIME_TYPE, n, [None, pa.py_buffer(times)]),
            pa.array(np.fromiter((r[0] for r in records), dtype=np.int64, count=n)),
            pa.array(np.fromiter((r[3] for r in records), dtype=np.uint32, count=n)),
            pa.Array.from_buffers(PAYLOAD_TYPE, n, [None, payloads]),
        ],
        schema=JOURNAL_SCHEMA,
    )


def expand(batch: pa.RecordBatch) -> pa.RecordBatch:
    """A journal batch of either form as a batch of the recording's schema (the payloads
    sliced into element columns; a batch of element columns comes back as it is)."""
    if not is_journal_form(batch.schema):
        return batch
    n = batch.num_rows
    payloads = batch.column(T2O_PAYLOAD)
    data = payloads.buffers()[1]
    start = payloads.offset * T2O_SIZE
    raw = np.frombuffer(data, dtype=np.uint8, count=n * T2O_SIZE, offset=start)
    return pa.RecordBatch.from_arrays(
        [
            batch.column(TIME),
            batch.column(SEQ),
            batch.column(T2O_SEQUENCE),
            *column_arrays(raw.reshape(n, T2O_SIZE)),
        ],
        schema=SCHEMA,
    )


__all__ = [
    "JOURNAL_SCHEMA",
    "T2O_PAYLOAD",
    "expand",
    "is_journal_form",
    "records_to_journal_batch",
]

"""Layer: layout tooling. Imports nothing of the project; ``grpc_tools`` (a dev dependency).

The Sparkplug B payload classes: ``cobot_hmi/sparkplug/sparkplug_b.proto`` compiled by
grpcio-tools' bundled ``protoc`` into ``generated/sparkplug_b_pb2.py`` (the messages) and
``generated/sparkplug_b_pb2.pyi`` (their types, for ``mypy --strict``). The generated module is
committed, so running the product needs only the ``protobuf`` runtime; grpcio-tools is pinned
in the dev dependencies because protoc's output names its version, and ``codegen --check``
compares byte for byte (docs/architecture.md, "Sparkplug B").
"""

from __future__ import annotations

import tempfile
from pathlib import Path

PROTO = Path(__file__).resolve().parents[1] / "sparkplug" / "sparkplug_b.proto"
MODULE = "sparkplug_b_pb2"


class ProtocMissingError(RuntimeError):
    """grpcio-tools is not installed (``pip install -e 'backend[dev]'``)."""


def sparkplug_modules() -> dict[str, str]:
    """``{"sparkplug_b_pb2.py": text, "sparkplug_b_pb2.pyi": text}`` as protoc writes them."""
    try:
        from grpc_tools import protoc  # type: ignore[import-untyped]
    except ImportError as error:
        raise ProtocMissingError(
            "generating the Sparkplug B classes needs grpcio-tools (the dev dependencies: "
            "pip install -e 'backend[dev]')"
        ) from error
    with tempfile.TemporaryDirectory(prefix="cobot-hmi-protoc-") as out:
        status = protoc.main(
            [
                "protoc",
                f"--proto_path={PROTO.parent}",
                f"--python_out={out}",
                f"--pyi_out={out}",
                PROTO.name,
            ]
        )
        if status != 0:
            raise RuntimeError(f"protoc failed on {PROTO.name} (exit {status})")
        return {
            f"{MODULE}{suffix}": (Path(out) / f"{MODULE}{suffix}").read_text(encoding="utf-8")
            for suffix in (".py", ".pyi")
        }

"""Layer: codec (pure). The codec's errors, in a module of their own so that the generated
frames module can raise them without importing ``cobot_hmi.codec``."""

from __future__ import annotations


class CodecError(ValueError):
    """Bytes or JSON that do not form a frame or a command image."""


class FrameSizeError(CodecError):
    """A T→O buffer shorter than its assembly, or an O→T image not exactly its size."""

    def __init__(self, what: str, expected: int, actual: int) -> None:
        super().__init__(f"{what}: expected {expected} bytes, got {actual}")
        self.expected = expected
        self.actual = actual

"""The decoders' 64 bit registers are taken from those decoded lately when their 8 bytes are the
same (``codegen/python_frames.py``, a bounded table): whatever the order of frames, however many
patterns (the table cleared when full), and from two threads at once, each decoded register
tuple is the one its own bytes say."""

from __future__ import annotations

import random
import threading

from cobot_hmi.codec import (
    decode_command,
    decode_frame,
    encode_command,
    encode_frame,
    zero_command,
    zero_frame,
)

T2O_REGISTERS_AT = 276
O2T_REGISTERS_AT = 12


def _bits(data: bytes, at: int) -> tuple[bool, ...]:
    return tuple(bool(data[at + i // 8] >> (i % 8) & 1) for i in range(64))


def _frame_bytes(registers: int, joint: float) -> bytes:
    bits = tuple(bool(registers >> i & 1) for i in range(64))
    return encode_frame(
        zero_frame()._replace(bit_output_registers=bits, joint_position=(joint,) * 6)
    )


def test_frames_in_any_order_decode_their_own_registers() -> None:
    rng = random.Random(40)
    patterns = [0, 1, 1 << 63, 0xFFFF_FFFF_FFFF_FFFF] + [rng.getrandbits(64) for _ in range(4)]
    sequence = [rng.choice(patterns) for _ in range(400)] + [patterns[2]] * 5 + [0, 0, 1, 1]
    sequence += [rng.getrandbits(64) for _ in range(700)] + patterns  # more than the table holds
    for n, registers in enumerate(sequence):
        data = _frame_bytes(registers, float(n))
        frame = decode_frame(data)
        assert frame.bit_output_registers == _bits(data, T2O_REGISTERS_AT)
        assert frame.joint_position == (float(n),) * 6
        assert encode_frame(frame) == data


def test_commands_in_any_order_decode_their_own_registers() -> None:
    rng = random.Random(41)
    for _ in range(200):
        registers = rng.choice((0, 5, rng.getrandbits(64)))
        bits = tuple(bool(registers >> i & 1) for i in range(64))
        data = encode_command(zero_command()._replace(bit_input_registers=bits))
        image = decode_command(data)
        assert image.bit_input_registers == _bits(data, O2T_REGISTERS_AT) == bits


def test_two_threads_decoding_at_once_each_get_their_own_registers() -> None:
    left, right = _frame_bytes(0x0123_4567_89AB_CDEF, 1.0), _frame_bytes(0xF0F0, 2.0)
    wrong: list[int] = []

    def decode(data: bytes) -> None:
        expected = _bits(data, T2O_REGISTERS_AT)
        for _ in range(20_000):
            if decode_frame(data).bit_output_registers != expected:
                wrong.append(1)

    threads = [threading.Thread(target=decode, args=(data,)) for data in (left, right)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert not wrong

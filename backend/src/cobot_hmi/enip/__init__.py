"""Layer: enip (pure EtherNet/IP packet code). Imports only the standard library and itself.

No sockets, no asyncio, no clocks: bytes in, typed values out, and back. Both roles build on
it, the target in ``cobot_hmi.emulator`` and the originator in ``cobot_hmi.scanner`` ("one
protocol core, two roles"). Every decoder raises a subclass of
:class:`cobot_hmi.enip.errors.EnipError` on malformed bytes, never ``IndexError`` or
``struct.error``.

Modules by responsibility:

- ``errors``: the typed decode errors.
- ``encapsulation``: the 24-byte header, commands, RegisterSession and SendRRData bodies.
- ``cpf``: Common Packet Format items, Sockaddr Info (big-endian).
- ``epath``: EPATH segments, connection paths, electronic keys.
- ``cip``: Message Router requests and responses, service codes.
- ``status``: general and extended status codes with their words.
- ``connection_manager``: Forward Open, Large Forward Open, Forward Close, network connection
  parameters, Unconnected Send.
- ``io``: the class 1 UDP packet (0x8002 + 0x00B1, CIP sequence count, run/idle header).
- ``sequence``: the class 1 receive rules (new, duplicate, stale, gaps) both roles apply.
- ``identity``: the Identity object's attributes and the ListIdentity item.
"""

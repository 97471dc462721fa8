"""Layer: scanner (I/O, the originator role). Imports the layout, the codec and
``cobot_hmi.enip``; never the emulator or the service. pycomm3 is imported in ``explicit``
only.

:class:`~cobot_hmi.scanner.originator.Originator` holds a class 1 connection to the robot (or any
adapter) as a PLC would; :class:`~cobot_hmi.scanner.io_port.IoPort` is the UDP 2222 socket the
connections of one local address share; ``session`` is its asyncio encapsulation client;
``explicit`` wraps pycomm3 for one-off explicit reads (the ``probe`` verb, the benchmark's
polling baseline).
"""

"""Layer: service (the top). The backend web service: REST and WebSocket API over the scanner.

It may import the layout, the codec, ``cobot_hmi.scanner`` and ``cobot_hmi.enip``; nothing
below imports it. It never imports ``cobot_hmi.emulator`` (the demo verb starts the emulator
as its own process).
"""

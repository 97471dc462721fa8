"""Layer: plant (a door above the service, beside ``sparkplug`` and ``opcua``). ``cobot-hmi
plant``: a Sparkplug 3.0 host application on the plant's brokers, its history and its own web
API (docs/operations.md "The plant"). Only the command line imports it."""

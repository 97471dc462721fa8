"""Layer: service. Events: the one event bus, events seen in frames, events in words."""

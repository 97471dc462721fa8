"""Layer: service. The routes of the REST and WebSocket API, one module per concern."""

"""Layer: service. The HTTP door: the FastAPI app, its routes, models, middlewares, metrics."""

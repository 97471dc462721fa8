"""Layer: service. The one write path of every door: authorize, validate, audit, apply, confirm."""

"""Layer: service. The settings' vocabulary, their loading from TOML, environment and flags."""

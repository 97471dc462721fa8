"""Layer: service. The integrator's commissioning tools: the I/O checkout (loop check) and the
output presets of each robot."""

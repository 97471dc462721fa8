"""Layer: service. The robots of the cell: each robot's link, frames, fan-out and control."""

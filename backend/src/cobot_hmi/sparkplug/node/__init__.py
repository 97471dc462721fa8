"""Layer: service (Sparkplug). The parts of the edge node
(:class:`~cobot_hmi.sparkplug.edge_node.EdgeNode`, which holds the MQTT session), a module per
concern: ``device`` (one robot as a device: its frames and what was reported), ``core`` (the
state the parts share, numbering and publishing), ``births`` (NBIRTH, DBIRTH, DDEATH, NDEATH's
payload, and the buffer's replay after a birth), ``reports`` (each robot's ticks: DDATA by
exception), ``command_handling`` (NCMD and DCMD), ``metrics`` (``/metrics``).
"""

"""Layer: service (Sparkplug). The parts of the edge node, each an object with one job, built
with what it needs and composed by :class:`~cobot_hmi.sparkplug.edge_node.EdgeNode`: ``device``
(one robot as a device: its frames and what was reported), ``core`` (what the parts share: the
node's status, background tasks, the ``Publisher`` that numbers, publishes and counts),
``replay`` (the buffer replayed after a birth), ``births`` (NBIRTH, DBIRTH, DDEATH, NDEATH),
``reports`` (each robot's ticks: DDATA by exception), ``command_handling`` (NCMD and DCMD),
``connection`` (the MQTT session and the primary host's STATE), ``metrics`` (``/metrics``).
"""

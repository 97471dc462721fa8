"""Layer: service (OPC UA). Every robot as an OPC UA server, in the Robotics companion
specification's shape (OPC 40010-1 over the Devices model, OPC 10000-100) and as a machine of
the Machinery building blocks (OPC 40001-1), with the whole I/O layout in a namespace of each
robot's own. Off unless ``opcua_url`` is set.

One concern per module: ``opcua_settings`` (declared once), ``companion`` (the OPC Foundation's
NodeSet files, the types named), ``nodes`` (adding nodes, instantiating types),
``robotics``, ``machinery`` and ``layout_nodes`` (one robot's instances and variables),
``address_space`` (every robot), ``bindings`` and ``values`` (the variables follow the
frames), ``units``, ``security`` (policies, certificate, trust list), ``auth`` (users and
permissions), ``writes`` and ``sessions`` (the command image and control through the write
pipeline), ``feed`` (the one adapter to the service), ``build_info`` (what the server says it
is), ``server`` (the thread and its loop).
"""

"""Layer: service (the Sparkplug B door). Imports the service's parts; never a route or the CLI.

The service as a Sparkplug B 3.0 edge node on an MQTT broker: each robot is a device whose
metrics are the layout's fields (``catalogue``), published by exception (``rbe``) under the
``spBv1.0`` namespace (``topics``) in protobuf payloads (``payload``, classes generated from
``sparkplug_b.proto``), with the node session's bdSeq/seq rules and NDEATH will
(``session``), a bounded disk buffer while the broker is away (``buffer``), DCMD writes
through the service's one write pipeline (``commands``), the MQTT connection
(``mqtt_client``) and the whole composed (``edge_node``, its parts in ``node/``). Off unless
``mqtt_url`` is set (docs/operations.md, "Sparkplug B").
"""

"""Layer: service. The alarm engine: per robot, evaluated on every frame (``docs/api.md``
"Alarms").

- ``definitions``: what an alarm is (key, words, priority and colour) and the built-in ones;
- ``state``: the ISA-18.2 alarm state machine with shelving (pure);
- ``conditions``: when a frame makes an alarm active (limits with deadband, on- and
  off-delays; bits; robot states), cheap enough for every frame (pure);
- ``engine``: one robot's alarms: frames, connection health, acknowledge, shelve, events;
- ``persistence``: current states and the history in the service's database.
"""

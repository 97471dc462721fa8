"""``python -m cobot_hmi.native``: build the cyclic pump now (``make venv`` and the images do) and
print where it is."""

from cobot_hmi.native import build

print(build())

"""``python -m cobot_hmi.native``: which cyclic pump loads here, and why. Exits 1 when
``COBOT_HMI_PUMP`` asks for one that cannot be had (``COBOT_HMI_PUMP=native`` in ``make venv``
and the images checks that the extension was built)."""

import os
import sys

from cobot_hmi.native import ENV_VAR, PumpUnavailableError, load_native, pump_class

native, reason = load_native()
print(f"extension: {'loads' if native is not None else 'cannot be loaded'} ({reason})")
try:
    _, implementation = pump_class()
except (PumpUnavailableError, ValueError) as error:
    print(f"error: {error}")
    sys.exit(1)
print(f"{ENV_VAR}={os.environ.get(ENV_VAR, '')!r}: the {implementation} pump is used")

import sys

from cobot_hmi.cli import main

sys.exit(main())

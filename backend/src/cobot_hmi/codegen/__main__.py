import sys

from cobot_hmi.codegen import main

sys.exit(main())

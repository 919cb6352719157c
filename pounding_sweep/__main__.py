"""`python -m pounding_sweep`: see cli.py."""

import sys

from pounding_sweep.cli import main

sys.exit(main())

"""``python -m nlo_lab.cli ARGS`` runs ``nlo-lab ARGS``."""

import sys

from nlo_lab.cli import main  # light: the signal handlers come first

sys.exit(main())

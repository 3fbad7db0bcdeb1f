"""``python -m nlo_lab.cli ARGS`` runs ``nlo-lab ARGS``."""

import sys

from nlo_lab.cli.app import main

sys.exit(main())

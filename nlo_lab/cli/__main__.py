"""``python -m nlo_lab.cli ARGS`` runs ``nlo-lab ARGS``."""

import sys  # built in: already loaded, nothing runs

from nlo_lab.__main__ import main  # its first lines take the signals, before any import of nlo_lab.cli

sys.exit(main())

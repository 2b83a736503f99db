"""``python -m flexkin.explore MECH.toml [--port P] [--no-browser] ...`` (same as ``flexkin explore``)."""

import sys

from .cli import main

sys.exit(main())

"""``python -m minimanc`` runs the ``minimanc`` command."""

import sys

from minimanc.cli import main

sys.exit(main())

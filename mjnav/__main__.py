"""``python -m mjnav`` is the ``mjnav`` command."""

import sys

from mjnav.cli import main

sys.exit(main())

"""``python -m uwcosim``."""

import sys

from uwcosim.cli import main

sys.exit(main())

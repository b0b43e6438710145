"""``python -m scanalign.cli``."""

import sys

from scanalign.cli.commands import main

sys.exit(main())

"""``python -m scanalign.cli``."""

from scanalign.cli.commands import main

raise SystemExit(main())

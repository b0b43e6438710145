"""``python -m scanalign.data fetch``: download and verify the real test data (see :mod:`.downloads`)."""

import sys

from scanalign.data.downloads import main

sys.exit(main())

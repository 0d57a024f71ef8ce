"""``python -m isochor``: the same as the ``isochor`` command."""

import sys

from isochor.app.cli import main

sys.exit(main())

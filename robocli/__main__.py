"""``python -m robocli`` is the ``robocli`` command."""

import sys

from robocli.cli import main

sys.exit(main())

"""``python -m loosefit``: the ``loosefit`` command."""

import sys

from loosefit.cli import main

sys.exit(main())

"""``python -m loosefit.cli`` (as torchrun's ``-m loosefit.cli train ...`` runs it)."""

import sys

from loosefit.cli import main

sys.exit(main())

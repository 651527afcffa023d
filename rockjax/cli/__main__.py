"""`python -m rockjax.cli`: the `rockjax` command."""

import sys

from . import main

sys.exit(main())

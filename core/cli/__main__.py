"""``python -m thermodrift.core.cli``: the same as the ``thermodrift`` console script."""

import sys

from thermodrift.core.cli import main

sys.exit(main())

"""``python -m tactilize.cli``: the same as the ``tactilize`` command."""

import sys

from . import main

sys.exit(main())

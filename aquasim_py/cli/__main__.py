"""``python -m aquasim_py.cli``: the ``aquasim-py`` command."""

import sys

from aquasim_py.cli import main

sys.exit(main())

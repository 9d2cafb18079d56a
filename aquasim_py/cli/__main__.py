"""``python -m aquasim_py.cli``: the ``aquasim-py`` command."""

import sys

from aquasim_py.cli import main

if __name__ == "__main__":  # importing the module (pkgutil, a docs tool) runs nothing
    sys.exit(main())

"""The installed distribution's version: a leaf module, so that modules the package's
``__init__`` reaches (the runner, output manifests) can name it without importing the
package back (no import cycle)."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("aquasim-py")
except PackageNotFoundError:  # running from a source tree without installation
    __version__ = "0.0.0+unknown"

__all__ = ["__version__"]

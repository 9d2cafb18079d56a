"""aquasim-py: discrete-event simulation of underwater acoustic sensor networks."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("aquasim-py")
except PackageNotFoundError:  # running from a source tree without installation
    __version__ = "0.0.0+unknown"

__all__ = ["__version__"]

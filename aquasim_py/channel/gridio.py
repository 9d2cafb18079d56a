"""Opening gridded ocean data (netCDF) with xarray, an optional dependency (``ocean`` extra).

netCDF3 files (what :mod:`tools.make_shelfbreak_sample` writes, what GEBCO's download app and
scipy write) are read through xarray's scipy engine; netCDF4 / HDF5 files (the World Ocean
Atlas's, GEBCO's global grid) through h5netcdf (or netCDF4 where that is installed instead).
"""

from __future__ import annotations

import importlib.util
from pathlib import Path
from typing import Any

__all__ = ["open_dataset"]


def _engine(p: Path) -> str | None:
    with p.open("rb") as f:
        magic = f.read(8)
    if magic[:3] == b"CDF":
        return "scipy"
    if magic == b"\x89HDF\r\n\x1a\n":
        for engine, module in (("h5netcdf", "h5netcdf"), ("netcdf4", "netCDF4")):
            if importlib.util.find_spec(module) is not None:
                return engine
        raise ImportError(f"{p}: a netCDF4 (HDF5) file needs h5netcdf: pip install 'aquasim-py[ocean]'")
    return None  # xarray's own guess (and its error for what is not netCDF)


def open_dataset(path: str | Path, **kwargs: Any) -> Any:
    """``xarray.open_dataset`` of ``path`` (keyword arguments passed on), its engine chosen by
    the file's first bytes."""
    try:
        import xarray as xr
    except ImportError as e:  # pragma: no cover - depends on the environment
        raise ImportError("reading a netCDF grid needs xarray: pip install 'aquasim-py[ocean]'") from e
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"{p}: no such file")
    return xr.open_dataset(p, engine=_engine(p), **kwargs)

"""Opening gridded ocean data (netCDF) with xarray, an optional dependency (``ocean`` extra).

netCDF3 files (what :mod:`tools.make_shelfbreak_sample` writes, and what scipy reads) need only
xarray and scipy; netCDF4/HDF5 files need the netCDF4 or h5netcdf package as well.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

__all__ = ["open_dataset"]


def open_dataset(path: str | Path) -> Any:
    """``xarray.open_dataset`` of ``path``, trying the scipy engine (netCDF3) first."""
    try:
        import xarray as xr
    except ImportError as e:  # pragma: no cover - depends on the environment
        raise ImportError("reading a netCDF grid needs xarray: pip install 'aquasim-py[ocean]'") from e
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"{p}: no such file")
    with p.open("rb") as f:
        magic = f.read(4)
    engine = "scipy" if magic[:3] == b"CDF" else None
    return xr.open_dataset(p, engine=engine)

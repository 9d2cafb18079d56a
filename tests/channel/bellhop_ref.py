"""BELLHOP (the Acoustics Toolbox's beam tracer, run in-process by the GPL ``pelagic`` package, a
test extra) on the same (range, depth) section as aquasim_py's range-dependent solver.

The section of one link (aquasim_py.channel.rangedep.sections) becomes a BELLHOP case: the
profile of its first column as a c-linear SSP (the comparisons use depth-only fields, where
BELLHOP's and our interpolations are the same function), the floor polyline as a linear
bathymetry (.bty, 'L'), or for a curved floor its dense samples as a curvilinear one ('C':
BELLHOP interpolates the normals between them), the sediment as an acoustic half-space, a vacuum
surface; run type 'A' (arrivals) with ``beams`` launch angles, at one receiver or several
(depths x ranges, one run). Not used by the package.
"""

from __future__ import annotations

import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np


def available() -> tuple[bool, str]:
    """(True, version) if pelagic imports here, else (False, the import error)."""
    try:
        import pelagic
    except Exception as e:  # pragma: no cover - depends on the environment
        return False, f"pelagic not importable: {e}"
    return True, str(pelagic.__version__)


@dataclass(frozen=True)
class BellhopArrivals:
    delay: np.ndarray  #: s (BELLHOP writes float32)
    amplitude: np.ndarray
    launch_deg: np.ndarray
    surface: np.ndarray
    bottom: np.ndarray
    receiver: np.ndarray  #: which receiver each arrival is at (0 for one)


def run(
    r: np.ndarray,
    floor_z: np.ndarray,
    z: np.ndarray,
    c: np.ndarray,
    zs: float,
    zr: float | np.ndarray,
    bottom: tuple[float, float, float],
    beams: int = 4001,
    angles_deg: tuple[float, float] = (-89.0, 89.0),
    frequency_hz: float = 1000.0,
    step_m: float = 0.0,
    R: float | np.ndarray | None = None,
    curved: bool = False,
    floor_r: np.ndarray | None = None,
) -> BellhopArrivals:
    """Arrivals at (R (default r[-1]), zr) from a source at (0, zs): section columns at ranges r (m)
    with floor depths floor_z (m), speeds c (m/s) on depths z (m), either one profile (K,) or
    one per column (J, K) (BELLHOP then interpolates bilinearly, option 'Q'); ``bottom`` =
    (speed m/s, density, attenuation dB per wavelength); ``step_m`` BELLHOP's ray step (0: its
    default, a tenth of the depth); ``curved``: (r, floor_z) are dense samples of a smooth floor
    (BELLHOP's curvilinear bathymetry) instead of the section's polyline; ``floor_r``: the
    ranges of ``floor_z`` where they are not the columns ``r`` (dense samples). ``zr`` and ``R`` arrays
    of one length, both increasing: that many receivers at (R[k], zr[k]) in one run (BELLHOP's
    irregular grid); the arrivals of all of them flattened (``BellhopArrivals.receiver``)."""
    import pelagic as pg

    zmax = float(np.max(floor_z))
    zs = float(zs)
    zr_k = np.atleast_1d(np.asarray(zr, float))
    R_k = np.atleast_1d(np.asarray(r[-1] if R is None else R, float))
    irregular = zr_k.size > 1
    # BELLHOP sorts the receiver depths and ranges each: an irregular grid's pairs must increase
    # in both (else it pairs them otherwise, silently)
    if irregular and not (np.all(np.diff(zr_k) > 0.0) and np.all(np.diff(R_k) > 0.0)):
        raise ValueError("bellhop_ref.run: several receivers must have increasing depths and ranges")
    # depth nodes at the floor to rounding are left to the last line (at zmax): BELLHOP ends the
    # profile at the first depth within rounding of zmax, and would read the next line as the
    # bottom's options
    keep = z < zmax - 1e-6
    zz = np.concatenate([z[keep], [zmax]])
    c2 = np.atleast_2d(np.asarray(c, float))  # (profiles, depths): one profile, or one per column r

    def on_zz(col: np.ndarray) -> np.ndarray:
        if zmax <= z[-1]:
            return np.interp(zz, z, col)
        return np.concatenate([col[keep], [col[-1] + (col[-1] - col[-2]) / (z[-1] - z[-2]) * (zmax - z[-1])]])

    cq = np.array([on_zz(col) for col in c2])
    cz = cq[0]
    quad = cq.shape[0] > 1  # range-dependent: BELLHOP's 'Q' (bilinear between profiles at r)
    R = float(R_k.max())
    bottom = tuple(float(v) for v in bottom)
    with tempfile.TemporaryDirectory(prefix="aquasim-bellhop-") as tmp:
        base = Path(tmp) / "case"
        lines = [
            "'aquasim section'",
            f"{frequency_hz}",
            "1",
            "'QVW'" if quad else "'CVW'",
            f"0 0.0 {zmax}",
        ]
        lines += [f"{float(zi)!r} {float(ci)!r} /" for zi, ci in zip(zz, cz)]
        cb, rho, att = bottom
        lines += [
            "'A*' 0.0",
            f"{zmax} {cb} 0.0 {rho} {att} /",
            "1",
            f"{zs} /",
            str(zr_k.size),
            " ".join(f"{float(v)!r}" for v in zr_k) + " /",
            str(R_k.size),
            " ".join(f"{float(v) / 1000.0!r}" for v in R_k) + " /",
            "'A   I'" if irregular else "'A'",
            f"{beams}",
            f"{angles_deg[0]} {angles_deg[1]} /",
            f"{float(step_m)!r} {zmax * 1.01 + 1.0} {R * 1.01 / 1000.0 + 0.01}",
        ]
        base.with_suffix(".env").write_text("\n".join(lines) + "\n")
        if quad:
            # the end profiles repeated far beyond both ends: BELLHOP needs c wherever a ray goes
            rq = np.concatenate([[min(r[0], 0.0) - 1e5], r, [max(r[-1], R) + 1e5]])
            cqx = np.concatenate([cq[:1], cq, cq[-1:]])
            ssp = [str(rq.size), " ".join(f"{float(v) / 1000.0!r}" for v in rq)]
            ssp += [" ".join(f"{float(v)!r}" for v in cqx[:, i]) for i in range(zz.size)]
            base.with_suffix(".ssp").write_text("\n".join(ssp) + "\n")
        # bathymetry: linear between points, ranges in km (extended a little past both ends)
        fr = r if floor_r is None else np.asarray(floor_r, float)
        rb = np.concatenate([[min(fr[0], 0.0) - 0.01 * R - 1.0], fr, [max(fr[-1], R) * 1.02 + 10.0]]) / 1000.0
        zb = np.concatenate([[floor_z[0]], floor_z, [floor_z[-1]]])
        bty = ["'C'" if curved else "'L'", str(rb.size)] + [f"{float(a)!r} {float(b)!r}" for a, b in zip(rb, zb)]
        base.with_suffix(".bty").write_text("\n".join(bty) + "\n")
        res = pg.bellhop.load(str(base.with_suffix(".env"))).run()
    a = res.arrivals
    return BellhopArrivals(
        delay=np.asarray(a.travel_time_s, float),
        amplitude=np.asarray(a.amplitude, float),
        launch_deg=np.asarray(a.source_angle_degrees, float),
        surface=np.asarray(a.top_bounces, int),
        bottom=np.asarray(a.bottom_bounces, int),
        receiver=np.repeat(np.arange(np.diff(a.arrival_offset).size), np.diff(a.arrival_offset).astype(np.intp)),
    )

"""The error tables of docs/channel.md: aquasim_py's range-dependent arrivals against the exact
layered solver, the ODE oracle (tests/channel/ray_ode_rd.py: the section's own medium and floor,
so on flat and planar floors; curved floors have their own table, tools/curved_floors.py) and
BELLHOP (pelagic; a curved floor as its curvilinear bathymetry through ours every 10 m, fans of
2001 beams one degree wide around each of our launch angles).

    python tools/arrivals_accuracy.py           # prints the three markdown tables

Cases: the test suite's (tests/channel/test_rangedep.py), each arrival of each case compared.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "channel"))


def main() -> None:
    import bellhop_ref  # type: ignore[import-not-found]
    import ray_ode_rd  # type: ignore[import-not-found]

    from aquasim_py.channel import eigenray, ssp
    from aquasim_py.channel.arrivals import arrivals
    from aquasim_py.channel.bathymetry import FluidBottom, Plane, Seamount
    from aquasim_py.channel.environment import Environment
    from aquasim_py.channel.fields import DepthProfile, RangeProfiles
    from aquasim_py.channel.rangedep import sections

    print("| profile (range-independent) | links | max abs difference of the first arrival, s |")
    print("|---|---|---|")
    rng = np.random.default_rng(2)
    for name, prof in (
        ("isogradient 0.05 1/s, 1000 m", ssp.Isogradient(1480.0, 0.05, bottom=1000.0)),
        ("4-layer duct, 1000 m", ssp.Layered([0, 50, 100, 300, 1000], [1520, 1518, 1495, 1490, 1500], bottom=1000.0)),
        ("Munk, 100 layers, 5000 m", ssp.Munk(bottom=5000.0, n_layers=100)),
    ):
        n = 200
        assert prof.bottom is not None
        D = float(prof.bottom)
        s = np.c_[rng.uniform(0, 5000, n), rng.uniform(0, 5000, n), rng.uniform(0, D, n)]
        d = np.c_[rng.uniform(0, 5000, n), rng.uniform(0, 5000, n), rng.uniform(0, D, n)]
        a = arrivals(Environment.from_profile(prof), s, d, max_bounces=1)
        ref = eigenray(prof, s, d, reflections="all").time
        print(f"| {name} | {n} | {np.nanmax(np.abs(a.first_delay - ref)):.1e} |")

    depths = [0, 30, 80, 200, 600]
    speeds = [[1500, 1498, 1485, 1482, 1484], [1510, 1506, 1492, 1486, 1485], [1525, 1520, 1500, 1490, 1486]]
    front = Environment(
        RangeProfiles([0, 3000, 6000], depths, speeds), Plane(150.0, slope_x=0.06), FluidBottom(1650, 1.9, 0.8)
    )
    wedge = Environment(DepthProfile(ssp.Constant(1500.0)), Plane(200.0, slope_x=-0.05), FluidBottom(1700.0, 1.5, 0.5))
    munk_slope = Environment(
        DepthProfile(ssp.Munk(bottom=None, n_layers=100)),
        Plane(5000.0, slope_x=-0.1, max_depth_m=5000.0),
        FluidBottom(),
    )
    seamount = Environment(
        DepthProfile(ssp.Munk(bottom=None, n_layers=60)),
        Seamount(3000.0, 2000.0, 3000.0, x0=8000.0, resolution_m=250.0),
        FluidBottom(),
    )
    print()
    print("| case | arrivals | max abs difference vs ODE, s | ODE's own error bound (largest), s |")
    print("|---|---|---|---|")
    for name, env, src, dst, mb in (
        ("front over a 6 % slope, 4.7 km", front, [500.0, 0.0, 40.0], [5200.0, 300.0, 120.0], 3),
        ("front over a 6 % slope, reversed, 4.7 km", front, [5500.0, -200.0, 300.0], [800.0, 100.0, 20.0], 3),
        ("ASA wedge, 3 km", wedge, [0.0, 0.0, 100.0], [3000.0, 0.0, 20.0], 4),
        ("Munk over a slope, 20 km", munk_slope, [0.0, 0.0, 1000.0], [20000.0, 0.0, 800.0], 2),
    ):
        a = arrivals(env, src, dst, max_bounces=mb)
        sec = sections(env, src, dst)
        r, c, fz = sec.link(0)
        med = ray_ode_rd.Medium(r, sec.z, c, fz)
        diffs, bounds = [], []
        for i in range(a.delay.size):
            ray, _ = ray_ode_rd.shoot(med, src[2], dst[2], a.launch_angle[i], int(a.bounce_code[i]), mb, sec.R[0])
            diffs.append(abs(ray.time - a.delay[i]))
            bounds.append(ray.time_bound)
        print(f"| {name} | {a.delay.size} | {max(diffs):.1e} | {max(bounds):.1e} |")

    print()
    print(
        "| case | arrivals | BELLHOP default step: max / median abs difference, s | BELLHOP 10 m step: max / median, s |"
    )
    print("|---|---|---|---|")
    for name, env, src, dst, mb in (
        ("ASA wedge, 1 km", wedge, [0.0, 0.0, 100.0], [1000.0, 0.0, 30.0], 4),
        ("ASA wedge, 3 km", wedge, [0.0, 0.0, 100.0], [3000.0, 0.0, 20.0], 4),
        ("Munk over a slope, 20 km", munk_slope, [0.0, 0.0, 1000.0], [20000.0, 0.0, 800.0], 2),
        ("Munk over a seamount, 15 km", seamount, [0.0, 0.0, 1500.0], [15000.0, 0.0, 1800.0], 3),
    ):
        a = arrivals(env, src, dst, max_bounces=mb, frequency_khz=1.0)
        sec = sections(env, src, dst)
        r, c, fz = sec.link(0)
        curved = bool(np.any(sec.floor_shape[:, 5:7] != 0.0))
        fr = np.linspace(r[0], r[-1], int(np.ceil((r[-1] - r[0]) / 10.0)) + 1) if curved else r
        ffz = sec.floor_at(0, fr) if curved else fz
        bottom = (env.bottom.sound_speed_mps, env.bottom.density, env.bottom.attenuation_db_per_wavelength)
        cells = []
        for step in (0.0, 10.0):
            d = []
            wins = [(th - 0.5, th + 0.5) for th in np.degrees(a.launch_angle)] if curved else [(-89.0, 89.0)]
            runs = [
                bellhop_ref.run(
                    r, ffz, sec.z, c[0], src[2], dst[2], bottom, beams=2001, angles_deg=w, step_m=step, R=sec.R[0],
                    curved=curved, floor_r=fr,
                )
                for w in wins
            ]  # fmt: skip
            for i in range(a.delay.size):
                b = runs[i if curved else 0]
                m = (b.surface == a.surface_bounces[i]) & (b.bottom == a.bottom_bounces[i])
                if m.any():
                    d.append(float(np.min(np.abs(b.delay[m] - a.delay[i]))))
            cells.append(f"{max(d):.1e} / {np.median(d):.1e}" if d else "none")
        print(f"| {name} | {a.delay.size} | {cells[0]} | {cells[1]} |")


if __name__ == "__main__":
    main()

"""Draw a ray fan through a layered profile and the straight-line range error (paper Fig. 2).

    python tools/plot_rays.py --out DIR

Writes DIR/ray_fan.png: left the sound-speed profile c(z) (10 isogradient layers with a
channel axis), right a fan of rays from one source, traced by integrating the ray equations
(scipy solve_ivp, surface and bottom reflections), with the layered solver's eigenrays to a
few receivers drawn on top (each must pass through its receiver).

Writes DIR/range_error.png: the range error of the straight-line model, E_r = t v - |x_T - x_A|
(Ramezani et al., eq 26), for b = 1480 m/s, a = 0.1 1/s, an anchor at the surface and targets
at a few depths, against the horizontal distance: left with v the best linear approximation
v_sl of eq 24, right for one depth with the other constant speeds the paper compares (speed
at the anchor, at the target, at the mean depth).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from scipy.integrate import solve_ivp

from aquasim_py.channel import Isogradient, Layered, PathKind, eigenray, isogradient

CHANNEL = Layered(
    [0, 50, 120, 200, 300, 420, 550, 700, 850, 1000, 1200],
    1500.0 + np.array([0, -5, -12, -20, -24, -20, -14, -8, -2, 4, 8.0]),
    bottom=1200.0,
)


def trace_ray(prof: Layered, z0: float, theta0: float, x_end: float, bottom: float) -> np.ndarray:
    """(x, z) samples of one ray (grazing angle theta0, positive down) with specular
    reflections at z = 0 and z = bottom; plain ODE integration, independent of the solver."""
    d, c = prof.depths, prof.speeds
    g = np.diff(c) / np.diff(d)

    def rhs(s, y):
        _x, z, th = y
        k = min(max(np.searchsorted(d, z, side="right") - 1, 0), g.size - 1)
        cz = c[k] + g[k] * (z - d[k])
        return [np.cos(th), np.sin(th), -np.cos(th) * g[k] / cz]

    def surface(s, y):
        return y[1]

    def floor(s, y):
        return y[1] - bottom

    def done(s, y):
        return y[0] - x_end

    # solve_ivp reads these attributes off the event functions (scipy's API; a function type
    # declares no such attributes)
    for ev in (surface, floor, done):
        ev.terminal = True  # type: ignore[attr-defined]
    surface.direction, floor.direction, done.direction = -1, 1, 1  # type: ignore[attr-defined]
    y = np.array([0.0, z0, theta0])
    out = [y[:2].copy()]
    s = 0.0
    for _ in range(50):
        sol = solve_ivp(rhs, (s, s + 3 * x_end), y, events=(surface, floor, done), max_step=20.0, rtol=1e-9, atol=1e-9)
        out.append(sol.y[:2].T)
        if sol.status != 1 or sol.t_events[2].size:
            break
        hit = 0 if sol.t_events[0].size else 1
        s = float(sol.t_events[hit][0])
        y = sol.y_events[hit][0].copy()
        y[1] = 0.0 if hit == 0 else bottom
        y[2] = -y[2]  # mirror the direction at the boundary
    return np.vstack(out)


def ray_fan(out: Path) -> Path:
    prof = CHANNEL
    if prof.bottom is None:
        raise ValueError("the ray fan needs a profile with a bottom")
    z_src, x_end, bottom = 250.0, 10_000.0, float(prof.bottom)
    fig, (ax_c, ax_r) = plt.subplots(1, 2, figsize=(12, 5), gridspec_kw={"width_ratios": [1, 4]}, sharey=True)
    z = np.linspace(0, bottom, 400)
    ax_c.plot(prof.speed(z), z, "k")
    ax_c.plot(prof.speeds, prof.depths, "k.", ms=4)
    ax_c.set_xlabel("c (m/s)")
    ax_c.set_ylabel("depth (m)")
    ax_c.set_title("profile (10 layers)")
    angles = np.deg2rad(np.linspace(-10, 10, 31))
    cmap = plt.get_cmap("coolwarm")
    for k, th in enumerate(angles):
        xz = trace_ray(prof, z_src, th, x_end, bottom)
        ax_r.plot(xz[:, 0] / 1e3, xz[:, 1], color=cmap(k / (len(angles) - 1)), lw=0.7)
    # the layered solver's first arrivals to a few receivers, traced from their launch angles
    rx = np.array([[2500.0, 0, 120.0], [4500.0, 0, 700.0], [7000.0, 0, 300.0], [9000.0, 0, 20.0]])
    src = np.array([0.0, 0.0, z_src])
    ray = eigenray(prof, src, rx, reflections="fallback")
    for i in range(len(rx)):
        if not np.isfinite(ray.launch_angle[i]):
            continue
        xz = trace_ray(prof, z_src, float(ray.launch_angle[i]), rx[i, 0], bottom)
        kind = PathKind(int(ray.path[i])).name.lower()
        ax_r.plot(xz[:, 0] / 1e3, xz[:, 1], "k", lw=2.0)
        ax_r.plot(rx[i, 0] / 1e3, rx[i, 2], "o", ms=8, mfc="yellow", mec="k")
        ax_r.annotate(
            f"{ray.time[i]:.4f} s ({kind})",
            (rx[i, 0] / 1e3, rx[i, 2]),
            textcoords="offset points",
            xytext=(6, 6),
            fontsize=8,
        )
    ax_r.plot(0, z_src, "k*", ms=12)
    ax_r.set_xlim(0, x_end / 1e3)
    ax_r.set_ylim(bottom, 0)
    ax_r.set_xlabel("range (km)")
    ax_r.set_title("ray fan from 250 m, -10 to +10 deg; black: solver eigenrays to the markers", fontsize=10)
    fig.tight_layout()
    path = out / "ray_fan.png"
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def range_error(out: Path) -> Path:
    b, a = 1480.0, 0.1
    r = np.linspace(10.0, 5000.0, 300)
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(12, 4.5))
    anchor = np.zeros((r.size, 3))
    for zt in (100.0, 300.0, 600.0, 1000.0):
        target = np.column_stack([r, np.zeros_like(r), np.full_like(r, zt)])
        t = isogradient.travel_time(b, a, anchor, target)
        dist = np.linalg.norm(target - anchor, axis=1)
        v_sl = dist / isogradient.straight_line_time(b, a, anchor, target)  # eq 24
        ax1.plot(r / 1e3, t * v_sl - dist, label=f"target depth {zt:.0f} m")
    ax1.set_xlabel("horizontal distance from the surface anchor (km)")
    ax1.set_ylabel("range error E_r = t v_sl - d (m)")
    ax1.set_title("straight-line model with v_sl (eq 24), b = 1480 m/s, a = 0.1 1/s")
    ax1.legend()
    zt = 500.0
    target = np.column_stack([r, np.zeros_like(r), np.full_like(r, zt)])
    t = isogradient.travel_time(b, a, anchor, target)
    dist = np.linalg.norm(target - anchor, axis=1)
    ssp = Isogradient(b, a)
    choices = {
        "speed at the anchor": np.full_like(r, b),
        "speed at the target": np.full_like(r, float(ssp.speed(zt))),
        "speed at the mean depth": np.full_like(r, float(ssp.speed(zt / 2))),
        "best linear approximation (eq 24)": dist / isogradient.straight_line_time(b, a, anchor, target),
    }
    for label, v in choices.items():
        ax2.plot(r / 1e3, t * v - dist, label=label)
    ax2.axhline(0, color="k", lw=0.5)
    ax2.set_xlabel("horizontal distance from the surface anchor (km)")
    ax2.set_ylabel("range error E_r = t v - d (m)")
    ax2.set_title(f"constant-speed choices, target at {zt:.0f} m")
    ax2.legend(fontsize=8)
    fig.tight_layout()
    path = out / "range_error.png"
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("."), help="output directory")
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    for p in (ray_fan(args.out), range_error(args.out)):
        print(p)


if __name__ == "__main__":
    main()

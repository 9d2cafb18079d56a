"""Ramezani et al. (IEEE TSP 2013): Monte Carlo reproductions of the trends of Figs. 6, 8
(localization) and 10, 11, 14 (tracking), each with its CRB / PCRB, as PNGs plus a markdown
table. Pure maths (vectorized over draws), no kernel: the network versions are the scenarios
scenarios/ramezani_*.toml.

    python tools/ramezani_figures.py [--out out/ramezani_figures] [--draws 10000] [--runs 300]

Set-ups (Section V): c(z) = 1480 + 0.1 z; the four tetrahedron vertices of the 100 m cube as
anchors (Fig. 14 adds the other four vertices one by one); localization targets = reference
point + N(0, 10^2 I) m, GN with K = 7, eps = 1e-3 from the anchors' centroid. GNA-ESSP is
the plain Algorithm 1 on the paper's formulas (eq 13 continued above the surface, where an
iterate may stray); the "water-only" column uses the channel's model, undefined above the
surface, and re-solves the rows where plain Algorithm 1 fails with the robust solver (step
halving + LM; their share is reported). Tracking as in tests/estimation/test_ramezani_tracking.py.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from ramezani_mc import TrackingMC, simulate_trajectories, tracking_monte_carlo  # tools/, beside this script

from aquasim_protocols.ramezani.math import (
    CUBE_VERTICES,
    PAPER_A,
    PAPER_B,
    TETRAHEDRON,
    batched_ekf,
    ddn_variance,
    essp_model,
    fix_crb,
    fix_crb_ddn,
    localize_batch,
    paper_transition,
    tof_functions,
)


def localization_point(
    ref: np.ndarray,
    sigma_t: float,
    draws: int,
    rng: np.random.Generator,
    a: float = PAPER_A,
    b: float = PAPER_B,
    anchors: np.ndarray = TETRAHEDRON,
    k_e_s2: float | None = None,
) -> dict:
    """One point of Figs. 6 / 7 / 8: RMSE of GNA-ESSP and GNA-ASSP and sqrt(mean CRB) (m).
    ``k_e_s2`` set: distance-dependent noise (eqs 34-36, Fig. 7) instead of ``sigma_t``; the
    estimators then stay the unweighted least squares of eq 29."""
    X = ref + 10.0 * rng.standard_normal((draws, 3))
    X[:, 2] = np.abs(X[:, 2])  # keep every target in the water (never triggers at z = 50 +- 10)
    tt, _ = essp_model(b, a)
    if k_e_s2 is None:
        std = np.full((draws, len(anchors)), sigma_t)
        crb = fix_crb(anchors, X, b, a, sigma_t)
    else:
        std = np.sqrt(ddn_variance(anchors, X, b, a, k_e_s2)[0])
        crb = fix_crb_ddn(anchors, X, b, a, k_e_s2)
        sigma_t = float(np.sqrt(np.mean(std**2)))  # only scales the whitened residuals
    t = tt(anchors, X[:, None, :]) + std * rng.standard_normal((draws, len(anchors)))
    row = {"sqrt_crb": float(np.sqrt(np.mean(crb))), "rms_noise_ms": float(1e3 * np.sqrt(np.mean(std**2)))}
    # essp: the paper's formulas (eq 13 continued above the surface), plain Algorithm 1;
    # essp_water: the model only in the water, failed rows re-solved (step halving + LM); assp
    for name, model, cont in (("essp", "essp", True), ("essp_water", "essp", False), ("assp", "assp", False)):
        tf, gf = tof_functions(model, b, a, anchors, continued=cont)
        Xe, ok, _rescued = localize_batch(anchors, t, tf, gf, sigma_t, anchors.mean(axis=0), rescue=not cont)
        e2 = np.sum((Xe - X) ** 2, axis=1)
        row[f"rmse_{name}"] = float(np.sqrt(np.nanmean(e2)))
        row[f"plain_fail_{name}"] = float(1.0 - ok.mean())
        row[f"unsolved_{name}"] = float(np.isnan(e2).mean())
        row[f"above_{name}"] = float(np.mean(Xe[:, 2] < 0.0))
    return row


def fig6(draws: int, seed: int) -> list[dict]:
    rng = np.random.default_rng(seed)
    rows = []
    for x in (50.0, 100.0, 200.0, 400.0, 700.0, 1000.0):
        r = localization_point(np.array([x, 50.0, 50.0]), 1e-3, draws, rng)
        rows.append({"x_ref": x, **r})
    return rows


#: K_E of Fig. 7 (s^2), our choice (the paper's "-10 dB" with l_r = 1000 m would mean ~30 ms of
#: noise at 100 m, so its unit is not ours): -40 dB gives ~0.9 ms at the cube's centre and
#: -60 dB ~0.09 ms, with l_r = 1000 m, beta = 2, L(f) = 1 dB/km as in Sec. V
K_E_FIG7 = (1e-4, 1e-6)


def fig7(draws: int, seed: int) -> list[dict]:
    rng = np.random.default_rng(seed)
    rows = []
    for k_e in K_E_FIG7:
        for x in (50.0, 100.0, 200.0, 400.0, 700.0, 1000.0):
            r = localization_point(np.array([x, 50.0, 50.0]), 0.0, draws, rng, k_e_s2=k_e)
            rows.append({"k_e": k_e, "x_ref": x, **r})
    return rows


def fig8(draws: int, seed: int) -> list[dict]:
    rng = np.random.default_rng(seed)
    rows = []
    for x in (50.0, 400.0):
        for a in (0.0, 0.02, 0.05, 0.1, 0.2, 0.3):
            r = localization_point(np.array([x, 50.0, 50.0]), 1e-3, draws, rng, a=a)
            rows.append({"x_ref": x, "a": a, **r})
    return rows


def fig10(seed: int, K: int = 500) -> dict:
    """One track from [3500, 50, 50] (Fig. 10): true path and both EKF estimates."""
    rng = np.random.default_rng(seed)
    S, _ = simulate_trajectories(rng, 1, K, [3500.0, 50.0, 50.0])
    X = S[:, 1:, :3]
    tt, _ = essp_model(PAPER_B, PAPER_A)
    tofs = tt(TETRAHEDRON, X[:, :, None, :]) + 1e-3 * rng.standard_normal((1, K, 4))
    depths = X[..., 2] + rng.standard_normal((1, K))
    Phi, Q = paper_transition(10.0)
    P0 = np.diag([30.0**2] * 3 + [0.01**2] * 3)
    prior = np.r_[S[0, 0, :3] + 30.0, np.zeros(3)]
    out = {"truth": X[0]}
    for m in ("essp", "assp"):
        tf, gf = tof_functions(m, PAPER_B, PAPER_A, TETRAHEDRON)
        out[m] = batched_ekf(tofs, depths, TETRAHEDRON, tf, gf, prior, P0, Phi, Q, 1e-3, 1.0, 10).x[0, 1:, :3]
    return out


def fig11(runs: int, seed: int) -> list[dict]:
    rows = []
    for x0 in (500.0, 1500.0):
        for s_ms in (0.01, 0.05, 0.1, 0.5, 1.0, 2.0):
            r = tracking_monte_carlo(runs, seed=seed, x0=(x0, 50.0, 50.0), sigma_t=s_ms * 1e-3, pcrb_runs=200)
            rows.append(
                {
                    "x0": x0,
                    "sigma_ms": s_ms,
                    "rmse_essp": r.rmse("essp"),
                    "rmse_assp": r.rmse("assp"),
                    "sqrt_pcrb": r.sqrt_pcrb(),
                    "rejected": r.rejected,
                }
            )
            seed += 1
    return rows


def fig14(runs: int, seed: int) -> list[dict]:
    rows = []
    for n in range(4, 9):
        r = tracking_monte_carlo(runs, seed=seed, anchors=CUBE_VERTICES[:n], pcrb_runs=200)
        rows.append(
            {"anchors": n, "rmse_essp": r.rmse("essp"), "rmse_assp": r.rmse("assp"), "sqrt_pcrb": r.sqrt_pcrb()}
        )
        seed += 1
    return rows


def tracking_curve(runs: int, seed: int) -> TrackingMC:
    """RMSE per frame at the paper's set-up (for the RMSE-vs-time panel)."""
    return tracking_monte_carlo(runs, seed=seed, pcrb_runs=200)


# --------------------------------------------------------------------------- output
def _plot_loc(rows: list[dict], xkey: str, xlabel: str, path: Path, title: str, logy: bool = True) -> None:
    fig, ax = plt.subplots(figsize=(6, 4))
    x = [r[xkey] for r in rows]
    ax.plot(x, [r["rmse_essp"] for r in rows], "o-", label="GNA-ESSP")
    ax.plot(x, [r["rmse_assp"] for r in rows], "s--", label="GNA-ASSP")
    ax.plot(x, [r["sqrt_crb"] for r in rows], "k:", label="sqrt(mean CRB)")
    ax.set_xlabel(xlabel)
    ax.set_ylabel("RMSE (m)")
    if logy:
        ax.set_yscale("log")
    ax.set_title(title)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def write_outputs(
    out: Path,
    f6: list[dict],
    f7: list[dict],
    f8: list[dict],
    f10: dict,
    f11: list[dict],
    f14: list[dict],
    curve: TrackingMC,
    draws: int,
    runs: int,
) -> str:
    out.mkdir(parents=True, exist_ok=True)
    _plot_loc(
        f6,
        "x_ref",
        "x of the reference point (m), y = z = 50",
        out / "fig6.png",
        "Fig. 6: RMSE vs distance, sigma_t = 1 ms",
    )
    for k_e in K_E_FIG7:
        _plot_loc(
            [r for r in f7 if r["k_e"] == k_e],
            "x_ref",
            "x of the reference point (m), y = z = 50",
            out / f"fig7_ke{10 * np.log10(k_e):.0f}dB.png",
            f"Fig. 7: distance-dependent noise, K_E = {10 * np.log10(k_e):.0f} dB",
        )
    fig, axs = plt.subplots(1, 2, figsize=(11, 4))
    for ax, x in zip(axs, (50.0, 400.0)):
        rr = [r for r in f8 if r["x_ref"] == x]
        a = [r["a"] for r in rr]
        ax.plot(a, [r["rmse_essp"] for r in rr], "o-", label="GNA-ESSP")
        ax.plot(a, [r["rmse_assp"] for r in rr], "s--", label="GNA-ASSP")
        ax.plot(a, [r["sqrt_crb"] for r in rr], "k:", label="sqrt(mean CRB)")
        ax.set_xlabel("SSP steepness a (1/s)")
        ax.set_ylabel("RMSE (m)")
        ax.set_title(f"Fig. 8: reference x = {x:g} m")
        ax.grid(True, alpha=0.3)
        ax.legend()
    fig.tight_layout()
    fig.savefig(out / "fig8.png", dpi=120)
    plt.close(fig)

    fig, axs = plt.subplots(1, 2, figsize=(11, 4))
    tr = f10["truth"]
    axs[0].plot(tr[:, 0], tr[:, 1], "k-", label="true")
    axs[0].plot(f10["essp"][:, 0], f10["essp"][:, 1], "-", lw=0.8, label="EKF-ESSP")
    axs[0].plot(f10["assp"][:, 0], f10["assp"][:, 1], "-", lw=0.8, label="EKF-ASSP")
    axs[0].set_xlabel("x (m)")
    axs[0].set_ylabel("y (m)")
    axs[0].set_title("Fig. 10: one track from [3500, 50, 50] (anchors at x <= 100 m)")
    axs[0].legend()
    k = np.arange(1, len(tr) + 1)
    for m in ("essp", "assp"):
        axs[1].semilogy(k, np.linalg.norm(f10[m] - tr, axis=1), lw=0.8, label=f"EKF-{m.upper()} error")
    axs[1].semilogy(np.arange(1, curve.pcrb.size + 1), np.sqrt(curve.pcrb), "k:", label="sqrt(mean PCRB), x0 = 500 m")
    axs[1].semilogy(
        np.arange(1, curve.pcrb.size + 1), np.sqrt(curve.mse["essp"]), "C0--", label="EKF-ESSP RMSE_k, x0 = 500 m"
    )
    axs[1].semilogy(
        np.arange(1, curve.pcrb.size + 1), np.sqrt(curve.mse["assp"]), "C1--", label="EKF-ASSP RMSE_k, x0 = 500 m"
    )
    axs[1].set_xlabel("frame k")
    axs[1].set_ylabel("error (m)")
    axs[1].legend(fontsize=7)
    axs[1].grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(out / "fig10.png", dpi=120)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(6, 4))
    for i, x0 in enumerate((500.0, 1500.0)):
        rr = [r for r in f11 if r["x0"] == x0]
        s = [r["sigma_ms"] for r in rr]
        ax.loglog(s, [r["rmse_essp"] for r in rr], "o-", color=f"C{i}", label=f"EKF-ESSP, x0 = {x0:g} m")
        ax.loglog(s, [r["rmse_assp"] for r in rr], "s--", color=f"C{i}", label=f"EKF-ASSP, x0 = {x0:g} m")
        ax.loglog(s, [r["sqrt_pcrb"] for r in rr], ":", color="k")
    ax.set_xlabel("sigma_t (ms)")
    ax.set_ylabel("RMSE over frames 300-500 (m)")
    ax.set_title("Fig. 11 (dotted: sqrt(mean PCRB))")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out / "fig11.png", dpi=120)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(6, 4))
    n = [r["anchors"] for r in f14]
    ax.plot(n, [r["rmse_essp"] for r in f14], "o-", label="EKF-ESSP")
    ax.plot(n, [r["rmse_assp"] for r in f14], "s--", label="EKF-ASSP")
    ax.plot(n, [r["sqrt_pcrb"] for r in f14], "k:", label="sqrt(mean PCRB)")
    ax.set_xlabel("number of anchors (cube vertices)")
    ax.set_ylabel("RMSE over frames 300-500 (m)")
    ax.set_title("Fig. 14")
    ax.grid(True, alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(out / "fig14.png", dpi=120)
    plt.close(fig)

    L = [
        f"### Fig. 6: RMSE vs distance (sigma_t = 1 ms, {draws} draws per point)",
        "",
        "| x_ref (m) | sqrt(mean CRB) (m) | GNA-ESSP RMSE (m) | ESSP / CRB | ESSP, water-only model + rescue (m) "
        "| its plain Alg. 1 failures | GNA-ASSP RMSE (m) | ASSP / CRB |",
        "|---|---|---|---|---|---|---|---|",
    ]
    L.extend(
        f"| {r['x_ref']:g} | {r['sqrt_crb']:.4g} | {r['rmse_essp']:.4g} | {r['rmse_essp'] / r['sqrt_crb']:.3f} "
        f"| {r['rmse_essp_water']:.4g} | {100 * r['plain_fail_essp_water']:.1f} % "
        f"| {r['rmse_assp']:.4g} | {r['rmse_assp'] / r['sqrt_crb']:.3f} |"
        for r in f6
    )
    L += [
        "",
        f"### Fig. 7: RMSE vs distance, distance-dependent noise (l_r = 1000 m, "
        f"beta = 2, L = 1 dB/km; {draws} draws per point)",
        "",
        "| K_E (s^2) | x_ref (m) | rms ToF noise (ms) | sqrt(mean CRB) (m) | GNA-ESSP RMSE (m) | ESSP / CRB "
        "| ESSP, water-only model + rescue (m) | its plain Alg. 1 failures | GNA-ASSP RMSE (m) | ASSP / CRB |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in f7:
        L.append(
            f"| {r['k_e']:g} | {r['x_ref']:g} | {r['rms_noise_ms']:.3g} | {r['sqrt_crb']:.4g} | {r['rmse_essp']:.4g} "
            f"| {r['rmse_essp'] / r['sqrt_crb']:.3f} | {r['rmse_essp_water']:.4g} "
            f"| {100 * r['plain_fail_essp_water']:.1f} % | {r['rmse_assp']:.4g} | {r['rmse_assp'] / r['sqrt_crb']:.3f} |"
        )
    L += [
        "",
        f"### Fig. 8: RMSE vs SSP steepness a (sigma_t = 1 ms, {draws} draws per point)",
        "",
        "| x_ref (m) | a (1/s) | GNA-ESSP RMSE (m) | sqrt(mean CRB) (m) | ESSP / CRB | GNA-ASSP RMSE (m) | ASSP / CRB |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in f8:
        L.append(
            f"| {r['x_ref']:g} | {r['a']:g} | {r['rmse_essp']:.4g} | {r['sqrt_crb']:.4g} "
            f"| {r['rmse_essp'] / r['sqrt_crb']:.3f} | {r['rmse_assp']:.4g} | {r['rmse_assp'] / r['sqrt_crb']:.3f} |"
        )
    L += [
        "",
        f"### Fig. 11: tracking RMSE over frames 300-500 vs sigma_t ({runs} trajectories per point)",
        "",
        "| x0 (m) | sigma_t (ms) | EKF-ESSP RMSE (m) | sqrt(mean PCRB) (m) | ESSP / PCRB | EKF-ASSP RMSE (m) | ASSP / PCRB |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in f11:
        L.append(
            f"| {r['x0']:g} | {r['sigma_ms']:g} | {r['rmse_essp']:.4g} | {r['sqrt_pcrb']:.4g} "
            f"| {r['rmse_essp'] / r['sqrt_pcrb']:.3f} | {r['rmse_assp']:.4g} | {r['rmse_assp'] / r['sqrt_pcrb']:.3f} |"
        )
    L += [
        "",
        f"### Fig. 14: tracking RMSE over frames 300-500 vs number of anchors (sigma_t = 1 ms, {runs} trajectories)",
        "",
        "| anchors | EKF-ESSP RMSE (m) | sqrt(mean PCRB) (m) | ESSP / PCRB | EKF-ASSP RMSE (m) |",
        "|---|---|---|---|---|",
    ]
    for r in f14:
        L.append(
            f"| {r['anchors']} | {r['rmse_essp']:.4g} | {r['sqrt_pcrb']:.4g} | {r['rmse_essp'] / r['sqrt_pcrb']:.3f} "
            f"| {r['rmse_assp']:.4g} |"
        )
    c = curve
    L += [
        "",
        f"### Tracking, paper set-up (x0 = [500, 50, 50], sigma_t = 1 ms, {runs} trajectories)",
        "",
        "| frames | EKF-ESSP RMSE (m) | EKF-ASSP RMSE (m) | sqrt(mean PCRB) (m) | mean distance to the anchors' centroid (m) |",
        "|---|---|---|---|---|",
    ]
    for k1, k2 in ((1, 100), (101, 200), (201, 300), (301, 400), (401, 500), (300, 500)):
        L.append(
            f"| {k1}-{k2} | {c.rmse('essp', k1, k2):.4g} | {c.rmse('assp', k1, k2):.4g} | {c.sqrt_pcrb(k1, k2):.4g} "
            f"| {c.distance[k1 - 1 : k2].mean():.0f} |"
        )
    L.append("")
    L.append(f"Trajectories redrawn because the depth random walk left the water: {100 * c.rejected:.0f} %.")
    text = "\n".join(L) + "\n"
    (out / "ramezani_figures.md").write_text(text)
    return text


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("out/ramezani_figures"))
    ap.add_argument("--draws", type=int, default=10_000, help="localization draws per point (paper: 1e4)")
    ap.add_argument("--runs", type=int, default=300, help="tracking trajectories per point (paper: 5000)")
    ap.add_argument("--seed", type=int, default=6)
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    f6 = fig6(args.draws, args.seed)
    f7 = fig7(args.draws, args.seed + 4)
    f8 = fig8(args.draws, args.seed + 1)
    f10 = fig10(args.seed + 2)
    curve = tracking_curve(args.runs, args.seed + 3)
    f11 = fig11(args.runs, args.seed + 100)
    f14 = fig14(args.runs, args.seed + 200)
    print(write_outputs(args.out, f6, f7, f8, f10, f11, f14, curve, args.draws, args.runs))
    print(f"({time.perf_counter() - t0:.0f} s; PNGs and ramezani_figures.md in {args.out})")


if __name__ == "__main__":
    main()

"""The figures of docs/network.md: the ambient noise (one definition, its four components and
the band integral) and the modulations' bit error rates against a Monte Carlo of each.

    python tools/phy_figures.py                  # writes docs/network/noise.png and ber.png
    python tools/phy_figures.py --out /tmp/figs --trials 20000

The Monte Carlo is the test suite's oracle (tests/channel/modem_mc.py: symbols through AWGN and
a demodulator, importance-sampled); each point is drawn with its 95 % interval.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "channel"))

from aquasim_py.channel import loss  # noqa: E402
from aquasim_py.channel.modem_presets import PRESETS  # noqa: E402
from aquasim_py.channel.phy import ber_bfsk_nc, ber_bpsk, ber_mfsk_nc  # noqa: E402
from aquasim_py.reporting.figures import plt, save_figure  # noqa: E402


def noise_figure(path: Path) -> None:
    """Left: the PSD's components and total (shipping 0.5, wind 0 and 10 m/s). Right: the noise
    power in each preset's band, integrated against the carrier approximation N(f_c) + 10 log B."""
    f = np.logspace(-2, 2.3, 400)  # kHz
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(11, 4.2))
    ax.semilogx(f, loss.noise_turbulence_db(f), ":", label="turbulence")
    for s in (0.0, 0.5, 1.0):
        ax.semilogx(f, loss.noise_shipping_db(f, s), "--", lw=0.8, label=f"shipping s={s:g}")
    for w in (0.0, 10.0):
        ax.semilogx(f, loss.noise_wind_db(f, w), "-.", lw=0.8, label=f"wind w={w:g} m/s")
    ax.semilogx(f, loss.noise_thermal_db(f), ":", label="thermal")
    for w in (0.0, 10.0):
        ax.semilogx(f, loss.noise_psd_db(f, 0.5, w), "k", lw=2 if w == 0 else 1, label=f"total (s=0.5, w={w:g})")
    ax.set_xlabel("frequency (kHz)")
    ax.set_ylabel("PSD (dB re 1 uPa^2/Hz)")
    ax.set_ylim(-20, 110)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    ax.set_title("ambient noise PSD (Coates / Stojanovic)")
    names, band, flat = [], [], []
    for p in PRESETS.values():
        lo, hi = p.frequency_khz - p.bandwidth_khz / 2, p.frequency_khz + p.bandwidth_khz / 2
        names.append(p.name)
        band.append(loss.noise_band_db(lo, hi))
        flat.append(float(loss.noise_psd_db(p.frequency_khz)) + 10 * np.log10(p.bandwidth_khz * 1e3))
    y = np.arange(len(names))
    bx.barh(y - 0.2, band, 0.4, label="integrated over the band")
    bx.barh(y + 0.2, flat, 0.4, label="N(f_c) + 10 log10 B")
    for k in y:
        bx.text(band[k] + 0.3, k - 0.2, f"{band[k] - flat[k]:+.2f} dB", va="center", fontsize=7)
    bx.set_yticks(y, names, fontsize=8)
    bx.set_xlim(50, 80)
    bx.set_xlabel("noise power in the band (dB re 1 uPa^2), shipping 0.5, wind 0")
    bx.legend(fontsize=7, loc="lower right")
    bx.set_title("each preset's band")
    save_figure(fig, path)


def ber_figure(path: Path, trials: int) -> None:
    """The closed forms (lines) and the Monte Carlo (points, 95 % intervals), 0-15 dB."""
    import modem_mc as mc  # type: ignore[import-not-found]

    rng = np.random.default_rng(1)
    db = np.arange(0, 16)
    g = 10.0 ** (db / 10.0)
    fig, ax = plt.subplots(figsize=(6.5, 4.6))
    cases = [
        ("BPSK / QPSK (coherent)", ber_bpsk, lambda d: mc.ber_psk(d, trials, rng)),
        ("QPSK, Monte Carlo", None, lambda d: mc.ber_psk(d, trials, rng, qpsk=True)),
        ("BFSK (non-coherent)", ber_bfsk_nc, lambda d: mc.ber_fsk_nc(d, 2, trials, rng)),
        ("4-FSK (non-coherent)", lambda x: ber_mfsk_nc(x, 4), lambda d: mc.ber_fsk_nc(d, 4, trials, rng)),
    ]
    for (label, closed, sim), color in zip(cases, ("C0", "C0", "C1", "C2"), strict=True):
        if closed is not None:
            ax.semilogy(db, [closed(x) for x in g], color=color, label=label)
        est = np.array([sim(float(d)) for d in db])
        marker = "s" if closed is None else "o"
        ax.errorbar(db, est[:, 0], yerr=1.96 * est[:, 1], fmt=marker, ms=4, mfc="none", color=color, capsize=2)
    ax.semilogy([], [], "ko", mfc="none", label="Monte Carlo, 95 % interval")
    ax.set_xlabel("Eb/N0 (dB)")
    ax.set_ylabel("bit error rate")
    ax.set_ylim(1e-17, 1)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title(f"closed forms vs symbols through AWGN ({trials} per point)")
    save_figure(fig, path)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "network")
    ap.add_argument("--trials", type=int, default=20_000, help="Monte Carlo trials per point")
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    noise_figure(args.out / "noise.png")
    ber_figure(args.out / "ber.png", args.trials)
    print(f"wrote {args.out / 'noise.png'} and {args.out / 'ber.png'}")


if __name__ == "__main__":
    main()

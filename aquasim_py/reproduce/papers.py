"""The five papers' claims, readings and scales, as data (see :mod:`.claims`).

Every number a claim compares with is the paper's own, with what it is a statistic of; every
reading is a named switch of the protocols (docs/<paper>.md describes it); the defaults of the
protocols are the literal readings, listed first.
"""

from __future__ import annotations

from .claims import Claim, Paper, Quantity, Reading, Scale

__all__ = ["PAPERS"]

Q = Quantity

# --------------------------------------------------------------------------------------- STVF
_STVF_RMSE = Q("stvf.avg_rmse_m", "stvf", label="STVF average RMSE (m)")
STVF = Paper(
    key="stvf",
    title="STVF (Hu et al., Sensors 2018) against SLMP",
    doc="docs/stvf.md",
    readings=(
        Reading("printed", "eqs 26-27 as printed: gamma = C1 eta + C2 f_z + C3 f_v, signed E (the defaults)"),
        Reading(
            "text",
            "eqs 26-27 as the text reads them: far and fast references ranked down (1 - f), |error| in E",
            variants={"stvf": "stvf_text"},
        ),
    ),
    claims=(
        Claim(
            "avg_rmse",
            "Sec. 5.2.3 / Table 1",
            "STVF's average RMSE at the Table 1 set-up",
            "value",
            _STVF_RMSE,
            "net",
            paper=7.09,
            paper_text="7.09 m (mean over unknown nodes of each node's RMSE)",
            statistic="mean over seeds of the mean over unknown nodes of each node's RMSE (stvf.avg_rmse_m)",
        ),
        Claim(
            "below_avg",
            "Sec. 5.2.3",
            "share of unknown nodes whose RMSE is below the average",
            "value",
            Q("stvf.share_below_avg", "stvf"),
            "net",
            paper=0.785,
            paper_text="78.5 % of the nodes",
            statistic="mean over seeds of the share of unknown nodes below the average RMSE",
        ),
        Claim(
            "converge5",
            "Fig. 6",
            "share of optimizations converged within 5 iterations",
            "value",
            Q("stvf.converge_within_5", "stvf"),
            "net",
            paper=0.89,
            paper_text="89 %",
            statistic="mean over seeds of the share of localizations with <= 5 iterations",
        ),
        Claim(
            "stvf_vs_slmp_rmse",
            "Fig. 7b",
            "STVF localizes more accurately than SLMP (density 16)",
            "less",
            Q("localization.rmse_m", "stvf"),
            "net",
            b=Q("localization.rmse_m", "slmp"),
            paper_text="STVF below SLMP",
            statistic="paired mean over seeds of RMSE(STVF) - RMSE(SLMP) over all estimates after the training",
        ),
        Claim(
            "coverage_vs_slmp",
            "Fig. 7a",
            "STVF's coverage a little higher than SLMP's",
            "less",
            Q("slmp.coverage", "slmp"),
            "net",
            b=Q("stvf.coverage", "stvf"),
            paper_text="STVF slightly above SLMP",
            statistic="paired mean over seeds of coverage(SLMP) - coverage(STVF), per-period coverage",
        ),
        Claim(
            "genie",
            "reference",
            "genie multilateration: every period, beacons' true positions, no promotion",
            "reference",
            Q("genie_multilateration.rmse_m", "genie_multilateration"),
            "net",
            statistic="mean over seeds of the RMSE over the genie's fixes",
            readings=("printed",),
        ),
        Claim(
            "crb",
            "reference",
            "CRB of the geometry STVF used (snapshot bound, references at their true positions)",
            "reference",
            Q("stvf.crb_rmse_m", "stvf"),
            "net",
            statistic="mean over seeds of sqrt(mean CRB over STVF's estimates)",
        ),
    ),
    quick=Scale(
        {"net": "scenarios/stvf_quick.toml"},
        runs=10,
        note="stvf_quick.toml: Table 1 scaled to 50 nodes on 250 m x 250 m (density 16), 60 s, scored from 20 s",
    ),
    full=Scale(
        {"net": "scenarios/stvf.toml"},
        runs=10,
        note="stvf.toml: Table 1 (200 nodes, 500 m x 500 m, range 80 m, 20 % beacons, 500 s), scored from 100 s",
    ),
)

# -------------------------------------------------------------------------------------- ITMTL
_SYNC = "sync.final_mean_abs_error_s"
_NMSE = "localization.nmse"


def _itmtl_less(cid: str, fig: str, metric: str, other: str, what: str) -> Claim:
    return Claim(
        cid,
        fig,
        f"ITMTL's {what} below {other}'s",
        "less",
        Q(metric, "itmtl"),
        "net",
        b=Q(metric, other),
        paper_text=f"ITMTL below {other} (curves lost: no number)",
        statistic=f"paired mean over seeds of {metric}(ITMTL) - {metric}({other})",
    )


ITMTL = Paper(
    key="itmtl",
    title="ITMTL (Gao et al.): joint sync and localization by iterative tracing",
    doc="docs/itmtl.md",
    readings=(
        Reading("round_trip", "phase 2 regresses on the round trip split by the motion term (the default)"),
        Reading(
            "model",
            "phase 2 regresses on the delay model's delay (eq 17) at the round's position",
            variants={"itmtl": "itmtl_model_delay", "wsc": "wsc_model_delay"},
        ),
    ),
    claims=(
        _itmtl_less("sync_vs_wsc", "Fig. 9", _SYNC, "wsc", "final sync error"),
        _itmtl_less("sync_vs_mobi", "Fig. 9", _SYNC, "mobi_sync", "final sync error"),
        _itmtl_less("sync_vs_tshl", "Fig. 9", _SYNC, "tshl", "final sync error"),
        _itmtl_less("nmse_vs_wsc", "Fig. 10", _NMSE, "wsc", "localization NMSE"),
        _itmtl_less("nmse_vs_mobi", "Fig. 10", _NMSE, "mobi_sync", "localization NMSE"),
        _itmtl_less("nmse_vs_tshl", "Fig. 10", _NMSE, "tshl", "localization NMSE"),
        Claim(
            "wsc_sync_gap",
            "Fig. 11",
            "without stratification compensation the time error is higher",
            "gap_pct",
            Q(_SYNC, "itmtl"),
            "net",
            b=Q(_SYNC, "wsc"),
            paper=56.67,
            paper_text="up to 56.67 % higher (largest over iterations)",
            statistic="100 (mean wsc - mean ITMTL) / mean ITMTL of the final sync error over seeds",
        ),
        Claim(
            "wsc_nmse_gap",
            "Fig. 12",
            "with compensation the NMSE is lower",
            "gap_pct",
            Q(_NMSE, "itmtl"),
            "net",
            b=Q(_NMSE, "wsc"),
            of="b",
            paper=25.8,
            paper_text="about 25.8 % lower",
            statistic="100 (mean wsc - mean ITMTL) / mean wsc of the run's NMSE over seeds",
        ),
        Claim(
            "coverage_of_bound",
            "Figs. 15-17 (reference)",
            "ITMTL coverage / the link graph's bound (nodes that can reach enough references)",
            "reference",
            Q("itmtl.coverage_of_bound", "itmtl"),
            "net",
            statistic="mean over seeds of coverage / coverage_upper_bound",
        ),
    ),
    quick=Scale(
        {"net": "scenarios/itmtl.toml"},
        runs=10,
        note="itmtl.toml: 4 references, 6 drifting sensors, 600 s (the paper's set-up survives only in prose)",
    ),
    full=Scale({"net": "scenarios/itmtl.toml"}, runs=100, note="itmtl.toml over 100 seeds"),
)

# ----------------------------------------------------------------------------------- Ramezani
RAMEZANI = Paper(
    key="ramezani",
    title="Ramezani, Jamali-Rad, Leus (IEEE TSP 2013): isogradient ToF localization and tracking",
    doc="docs/ramezani.md",
    readings=(Reading("printed", "the paper's equations as printed (nothing was lost)"),),
    claims=(
        Claim(
            "gna_essp_on_crb",
            "Figs. 6-8",
            "GNA-ESSP attains the CRB",
            "ratio",
            Q("ramezani.localization_essp.rmse_m", statistic="rms"),
            "loc",
            b=Q("ramezani.localization_essp.sqrt_mean_crb_m", statistic="rms"),
            paper=1.0,
            paper_text="on the mean CRB (RMSE / sqrt(mean CRB) = 1)",
            statistic="RMSE over every fix of every seed / sqrt(mean CRB over the same fixes)",
        ),
        Claim(
            "gna_essp_vs_assp",
            "Figs. 6-8",
            "GNA-ESSP more accurate than GNA-ASSP (which saturates)",
            "less",
            Q("ramezani.localization_essp.rmse_m"),
            "loc",
            b=Q("ramezani.localization_assp.rmse_m"),
            paper_text="ESSP below ASSP",
            statistic="paired mean over seeds of RMSE(ESSP) - RMSE(ASSP)",
        ),
        Claim(
            "ekf_essp_on_pcrb",
            "Figs. 11, 14",
            "EKF-ESSP attains the PCRB over steps 300-500",
            "ratio",
            Q("ramezani.tracking_essp.rmse_m", statistic="rms"),
            "track",
            b=Q("ramezani.tracking_essp.sqrt_mean_pcrb_m", statistic="rms"),
            paper=1.0,
            paper_text="on the PCRB (RMSE / sqrt(mean PCRB) = 1)",
            statistic="RMSE over steps 300-500 of every seed's trajectory / sqrt(mean PCRB over the same steps); "
            "the PCRB of each trajectory along its own truth",
        ),
        Claim(
            "ekf_essp_vs_assp",
            "Figs. 11, 14",
            "EKF-ESSP more accurate than EKF-ASSP",
            "less",
            Q("ramezani.tracking_essp.rmse_m"),
            "track",
            b=Q("ramezani.tracking_assp.rmse_m"),
            paper_text="ESSP below ASSP",
            statistic="paired mean over seeds of RMSE(ESSP) - RMSE(ASSP) over steps 300-500",
        ),
    ),
    quick=Scale(
        {"loc": "scenarios/ramezani_localization.toml", "track": "scenarios/ramezani_tracking.toml"},
        runs=10,
        note="200 fixes per localization run, one 500-step trajectory per tracking run",
    ),
    full=Scale(
        {"loc": "scenarios/ramezani_localization.toml", "track": "scenarios/ramezani_tracking.toml"},
        runs=100,
        note="100 seeds of each (the paper: 10^4 draws per point with the maths alone, tools/ramezani_mc.py)",
    ),
)

# -------------------------------------------------------------------------------------- MSWPF
_MSWPF_T1 = {  # Table 1 (2-D, r_x = 0, Ns = 3): L -> (GW, EW, BW) in m
    2: (27.05, 31.80, 31.92),
    4: (11.38, 13.95, 18.14),
    6: (7.312, 9.694, 14.30),
    8: (6.265, 8.581, 13.15),
}


def _mswpf_claims() -> tuple[Claim, ...]:
    out: list[Claim] = []
    stat = "RMS over runs of each run's RMSE over the 80 intervals (pooled RMSE; eq 37 averages per-interval RMSEs)"
    for L, vals in _MSWPF_T1.items():
        over = (f"nodes.1.params.levels={L}",)
        for w, v in zip(("gw", "ew", "bw"), vals):
            out.append(
                Claim(
                    f"t1_{w}_L{L}",
                    "Table 1",
                    f"{w.upper()} RMSE at L = {L}",
                    "value",
                    Q("mswpf.rmse_m", w, statistic="rms"),
                    "2d",
                    paper=v,
                    paper_text=f"{v} m (eq 37, 100 Monte Carlo runs)",
                    statistic=stat,
                    overrides=over,
                )
            )
        for x, y in (("gw", "ew"), ("ew", "bw")):
            out.append(
                Claim(
                    f"t1_{x}_lt_{y}_L{L}",
                    "Table 1",
                    f"{x.upper()} < {y.upper()} at L = {L}",
                    "less",
                    Q("mswpf.rmse_m", x, statistic="rms"),
                    "2d",
                    b=Q("mswpf.rmse_m", y, statistic="rms"),
                    paper_text=f"{x.upper()} below {y.upper()}",
                    statistic="difference of the pooled RMSEs, paired bootstrap over runs",
                    overrides=over,
                )
            )
    for w, v in (("gw", 13.26), ("ew", 17.20)):
        out.append(
            Claim(
                f"t3_{w}",
                "Table 3",
                f"3-D {w.upper()} RMSE (Ns = 3, L = 8)",
                "value",
                Q("mswpf.rmse_m", w, statistic="rms"),
                "3d",
                paper=v,
                paper_text=f"{v} m",
                statistic=stat.replace("80", "60"),
            )
        )
    out.append(
        Claim(
            "t3_gw_lt_ew",
            "Table 3",
            "3-D GW < EW (Ns = 3)",
            "less",
            Q("mswpf.rmse_m", "gw", statistic="rms"),
            "3d",
            b=Q("mswpf.rmse_m", "ew", statistic="rms"),
            paper_text="GW below EW",
            statistic="difference of the pooled RMSEs, paired bootstrap over runs",
        )
    )
    return tuple(out)


MSWPF = Paper(
    key="mswpf",
    title="MSWPF (Zhang et al.): MI-weighted multi-sensor particle filter with PCRLB selection",
    doc="docs/mswpf.md",
    readings=(
        Reading("printed", "eq 6 as printed (k = 2, S = 5e4), the paper's CV truth q = 1 kept in the field"),
        Reading(
            "former",
            "the former defaults: k = 1 (amplitude as 1/D), truth the straight CV line (q = 0)",
            variants={"gw": "gw_former", "ew": "ew_former", "bw": "bw_former"},
        ),
    ),
    claims=_mswpf_claims(),
    quick=Scale(
        {"2d": "scenarios/mswpf_2d.toml", "3d": "scenarios/mswpf_3d.toml"},
        runs=10,
        overrides=("nodes.1.params.ideal_links=true",),
        note="the paper's instantaneous fusion (ideal links); 10 runs per cell (the paper: 100)",
    ),
    full=Scale(
        {"2d": "scenarios/mswpf_2d.toml", "3d": "scenarios/mswpf_3d.toml"},
        runs=100,
        overrides=("nodes.1.params.ideal_links=true",),
        note="the paper's instantaneous fusion (ideal links); 100 runs per cell, as the paper",
    ),
)

# -------------------------------------------------------------------------------------- SVL-PF
_SV_TABLES = {  # scenario key -> (table, SVL-PF, LSSVR-PF, ToA-PF) at k = 100, m
    "s1": ("Table 2", 2.50, 3.86, 4.29),
    "s2": ("Table 3", 3.45, 8.22, 6.50),
}
_ALSO = 'nodes.0.params.also=["toa_pf", "lssvr_pf", "consensus"]'


def _svlpf_claims() -> tuple[Claim, ...]:
    out: list[Claim] = []
    for sc, (table, sv, ls, toa) in _SV_TABLES.items():
        readings = ("printed", "repaired") if sc == "s1" else ()
        stat = "mean over seeds of eq 32's accumulated error at k = 100"
        for algo, v in (("svlpf", sv), ("lssvr_pf", ls), ("toa_pf", toa)):
            out.append(
                Claim(
                    f"{sc}_{algo}",
                    table,
                    f"{algo} accumulated error, Scenario {sc[1]}",
                    "value",
                    Q(f"svlpf.{algo}.accumulated_error_m", "svlpf", label=f"{algo} (m)"),
                    sc,
                    paper=v,
                    paper_text=f"{v} m at k = 100",
                    statistic=stat,
                    readings=readings,
                )
            )
        out.extend(
            Claim(
                f"{sc}_svlpf_lt_{other}",
                table,
                f"SVL-PF below {other}, Scenario {sc[1]}",
                "less",
                Q("svlpf.svlpf.accumulated_error_m", "svlpf"),
                sc,
                b=Q(f"svlpf.{other}.accumulated_error_m", "svlpf"),
                paper_text="SVL-PF lowest",
                statistic="paired mean over seeds of the difference of accumulated errors at k = 100",
                readings=readings,
            )
            for other in ("lssvr_pf", "toa_pf")
        )
        out.append(
            Claim(
                f"{sc}_consensus_own",
                f"{table} (reference)",
                "consensus (own construction): not the cited paper's method, no verdict",
                "reference",
                Q("svlpf.consensus.accumulated_error_m", "svlpf"),
                sc,
                statistic=stat,
                readings=readings,
            )
        )
    return tuple(out)


SVLPF = Paper(
    key="svlpf",
    title="SVL-PF (Li et al., Sensors 2018): support-vector-learning particle filter",
    doc="docs/svlpf.md",
    readings=(
        Reading("printed", "eqs 21, 25, 26 as printed; Scenario 2 as printed (25 % on every link)"),
        Reading(
            "repaired",
            "eqs 21, 25, 26 repaired (diagnosis on the excess loss, delta clipped, iterated regression)",
            variants={"svlpf": "svlpf_repaired"},
        ),
        Reading(
            "printed_obstructed",
            "eqs as printed; Scenario 2's excess noise on obstructed links (20 %, 30 dB, half-normal 25 % late)",
            scenarios={"s2": "s2_obstructed"},
        ),
        Reading(
            "repaired_obstructed",
            "eqs repaired; Scenario 2's excess noise on obstructed links",
            variants={"svlpf": "svlpf_repaired"},
            scenarios={"s2": "s2_obstructed"},
        ),
    ),
    claims=_svlpf_claims(),
    quick=Scale(
        {
            "s1": "scenarios/svlpf_gaussian.toml",
            "s2": "scenarios/svlpf.toml",
            "s2_obstructed": "scenarios/svlpf_obstructed.toml",
        },
        runs=10,
        overrides=(_ALSO,),
        note="100 frames per run, the four estimators on one network per seed; 10 seeds",
    ),
    full=Scale(
        {
            "s1": "scenarios/svlpf_gaussian.toml",
            "s2": "scenarios/svlpf.toml",
            "s2_obstructed": "scenarios/svlpf_obstructed.toml",
        },
        runs=100,
        overrides=(_ALSO,),
        note="100 frames per run, the four estimators on one network per seed; 100 seeds",
    ),
)

PAPERS: dict[str, Paper] = {p.key: p for p in (ITMTL, STVF, RAMEZANI, MSWPF, SVLPF)}

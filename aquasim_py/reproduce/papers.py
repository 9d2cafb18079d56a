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
#: Sec. 5.2.3: "we select the threshold of the measurements' number as 3, choose the number of
#: the samples as 200" (Table 1's Nr = 3 is the default; Ns = Nv = 200 instead of Table 1's 100)
_STVF_523 = ("nodes.1.params.n_samples=200",)
#: Sec. 5.3.1 (Fig. 7): "we set the threshold of the measurements' number to be 2"
_STVF_FIG7 = ("nodes.1.params.n_ref=2",)
#: the metrics the claims read, each also scored after the training (reading ``*_after_training``)
_STVF_WINDOW = "after_training"


def _stvf_q(metric: str, variant: str, over: tuple[str, ...], label: str = "") -> Quantity:
    return Q(metric, variant, label=label, overrides=over)


def _stvf_claims() -> tuple[Claim, ...]:
    sec523 = "Sec. 5.2.3 (Nr = 3, Ns = 200)"
    fig7 = "Fig. 7 (density 16, Nr = 2)"
    return (
        Claim(
            "avg_rmse",
            sec523,
            "STVF's average RMSE over the unknown nodes",
            "value",
            _stvf_q("stvf.avg_rmse_m", "stvf", _STVF_523, "STVF average RMSE (m)"),
            "net",
            paper=7.09,
            paper_text="7.09 m (mean over unknown nodes of each node's RMSE over the instants it is localized)",
            statistic="mean over seeds of the mean over unknown nodes of each node's RMSE (stvf.avg_rmse_m)",
        ),
        Claim(
            "below_avg",
            sec523,
            "share of unknown nodes whose RMSE is below the average",
            "value",
            _stvf_q("stvf.share_below_avg", "stvf", _STVF_523),
            "net",
            paper=0.785,
            paper_text="78.5 % of the unknown nodes",
            statistic="mean over seeds of the share of unknown nodes below the average RMSE",
        ),
        Claim(
            "converge5",
            f"{sec523} / Fig. 6",
            "share of optimizations converged within 5 iterations",
            "value",
            _stvf_q("stvf.converge_within_5", "stvf", _STVF_523),
            "net",
            paper=0.8907,
            paper_text="89.07 %",
            statistic="mean over seeds of the share of localizations with <= 5 iterations",
        ),
        Claim(
            "mean_iterations",
            f"{sec523} / Fig. 6",
            "mean number of iterations of an optimization",
            "value",
            _stvf_q("stvf.mean_iterations", "stvf", _STVF_523),
            "net",
            paper=4.64,
            paper_text="4.64 iterations on average",
            statistic="mean over seeds of the mean iterations per localization",
        ),
        Claim(
            "max_iterations",
            f"{sec523} / Fig. 6",
            "largest number of iterations of an optimization",
            "value",
            _stvf_q("stvf.max_iterations", "stvf", _STVF_523),
            "net",
            paper=7.0,
            paper_text="7 at most",
            statistic="mean over seeds of the run's largest iteration count",
        ),
        Claim(
            "stvf_vs_slmp_error",
            fig7 + " b",
            "STVF localizes more accurately than SLMP",
            "less",
            _stvf_q("stvf.mean_error_m", "stvf", _STVF_FIG7, "STVF mean error (m)"),
            "net",
            b=Q("slmp.mean_error_m", "slmp", label="SLMP mean error (m)"),
            paper_text="STVF below SLMP (Sec. 5.1: average distance between estimated and real locations)",
            statistic="paired mean over seeds of mean_error(STVF) - mean_error(SLMP), every estimate of the window",
        ),
        Claim(
            "coverage_vs_slmp",
            fig7 + " a",
            "STVF's coverage a little higher than SLMP's",
            "less",
            Q("slmp.coverage", "slmp"),
            "net",
            b=_stvf_q("stvf.coverage", "stvf", _STVF_FIG7),
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
            readings=("printed", f"printed_{_STVF_WINDOW}"),
        ),
        Claim(
            "crb",
            "reference",
            "CRB of the geometry STVF used at Sec. 5.2.3's set-up (snapshot bound, references at their true positions)",
            "reference",
            _stvf_q("stvf.crb_rmse_m", "stvf", _STVF_523),
            "net",
            statistic="mean over seeds of sqrt(mean CRB over STVF's estimates)",
        ),
    )


STVF = Paper(
    key="stvf",
    title="STVF (Hu et al., Sensors 2018) against SLMP",
    doc="docs/stvf.md",
    readings=(
        Reading(
            "printed",
            "eqs 26-27 as printed: gamma = C1 eta + C2 f_z + C3 f_v, signed E (the defaults); "
            "scored at every instant a node is localized (Sec. 5.2.3)",
        ),
        Reading(
            "text",
            "eqs 26-27 as the text reads them: far and fast references ranked down (1 - f), |error| in E",
            variants={"stvf": "stvf_text"},
        ),
        Reading(
            f"printed_{_STVF_WINDOW}",
            "eqs 26-27 as printed, scored only after the first 100 s (Sec. 5.3's beacon training; quick: 20 s)",
            window=_STVF_WINDOW,
        ),
        Reading(
            f"text_{_STVF_WINDOW}",
            "eqs 26-27 as the text reads them, scored only after the training",
            variants={"stvf": "stvf_text"},
            window=_STVF_WINDOW,
        ),
    ),
    claims=_stvf_claims(),
    quick=Scale(
        {"net": "scenarios/stvf_quick.toml"},
        runs=10,
        overrides=("metrics.warmup_s=0.0",),
        windows={_STVF_WINDOW: 20.0},
        note="stvf_quick.toml: Table 1 scaled to 50 nodes on 250 m x 250 m (density 16), 60 s; 10 seeds "
        "(the paper: 50 runs of the full set-up)",
    ),
    full=Scale(
        {"net": "scenarios/stvf.toml"},
        runs=50,
        overrides=("metrics.warmup_s=0.0",),
        windows={_STVF_WINDOW: 100.0},
        note="stvf.toml: Table 1 (200 nodes, 500 m x 500 m, range 80 m, 20 % beacons, 500 s); "
        "50 seeds, as the paper's 'each simulation is run 50 times'",
    ),
)

# -------------------------------------------------------------------------------------- ITMTL
_SYNC = "sync.final_mean_abs_error_s"
_NMSE = "localization.nmse"
#: Figs 9-12: "the localization process with anchor nodes as the reference nodes is only
#: studied in this simulation": no promotion (reading ``promotion`` turns it on); the
#: baselines never promote (they have no such parameter)
_ITMTL_VARIANTS = ("itmtl", "wsc", "itmtl_model_delay", "wsc_model_delay")
_ANCHORS_ONLY: dict[str, tuple[str, ...]] = dict.fromkeys(_ITMTL_VARIANTS, ("nodes.1.params.promotion=false",))
#: Fig. 13: "without any tracking algorithm": the raw fixes (its own runs, paired by seed)
_NO_IMM = ("nodes.1.params.imm=false",)


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
        Reading(
            "round_trip",
            "anchors only (the paper's set-up of Figs 9-12); phase 2 regresses on the round trip split by "
            "the motion term (the default)",
        ),
        Reading(
            "model",
            "anchors only; phase 2 regresses on the delay model's delay (eq 17) at the round's position",
            variants={"itmtl": "itmtl_model_delay", "wsc": "wsc_model_delay"},
        ),
        Reading(
            "promotion",
            "promotion on (the network-wide construction of Figs 15-17: confident ordinary nodes become "
            "references); round-trip delays",
            variant_overrides=dict.fromkeys(_ITMTL_VARIANTS, ("nodes.1.params.promotion=true",)),
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
            "without stratification compensation the time error is higher, up to 56.67 % at the same iteration",
            "gap_pct",
            Q("itmtl.sync_error_s", "itmtl", statistic="interval_mean"),
            "net",
            b=Q("itmtl.sync_error_s", "wsc", statistic="interval_mean"),
            paper=56.67,
            paper_text="up to 56.67 % higher (largest difference over iterations)",
            statistic="largest over rounds of 100 (wsc - ITMTL) / ITMTL of the round's mean |sync error| of the "
            "localized ordinary nodes, averaged over seeds",
            reduce="max",
        ),
        Claim(
            "wsc_sync_gap_final",
            "Fig. 11 (reference)",
            "the same gap on the final sync error (another statistic than the paper's: no verdict)",
            "gap_pct",
            Q(_SYNC, "itmtl"),
            "net",
            b=Q(_SYNC, "wsc"),
            statistic="100 (mean wsc - mean ITMTL) / mean ITMTL of the final sync error over seeds",
        ),
        Claim(
            "wsc_nmse_gap",
            "Fig. 12",
            "with compensation the NMSE is about 25.8 % lower at the same iteration",
            "gap_pct",
            Q("itmtl.nmse", "itmtl", statistic="interval_mean"),
            "net",
            b=Q("itmtl.nmse", "wsc", statistic="interval_mean"),
            of="b",
            paper=25.8,
            paper_text="about 25.8 % lower (at the same iteration)",
            statistic="median over rounds of 100 (wsc - ITMTL) / wsc of the round's NMSE averaged over seeds",
            reduce="median",
        ),
        Claim(
            "wsc_nmse_gap_run",
            "Fig. 12 (reference)",
            "the same gap on the run's NMSE (another statistic than the paper's: no verdict)",
            "gap_pct",
            Q(_NMSE, "itmtl"),
            "net",
            b=Q(_NMSE, "wsc"),
            of="b",
            statistic="100 (mean wsc - mean ITMTL) / mean wsc of the run's NMSE over seeds",
        ),
        Claim(
            "imm_vs_raw",
            "Fig. 13",
            "IMM tracing gives a lower NMSE than no tracking (at the scenario's current, iota = 3)",
            "less",
            Q(_NMSE, "itmtl"),
            "net",
            b=Q(_NMSE, "itmtl", label="itmtl without IMM: localization.nmse", overrides=_NO_IMM),
            paper_text="IMM always below no tracking (the mobility coefficient's definition was lost)",
            statistic="paired mean over seeds of NMSE(IMM) - NMSE(raw fixes)",
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
        variant_overrides=_ANCHORS_ONLY,
        note="itmtl.toml: 4 references, 6 drifting sensors, 600 s (the paper's set-up survives only in prose)",
    ),
    full=Scale(
        {"net": "scenarios/itmtl.toml"},
        runs=100,
        variant_overrides=_ANCHORS_ONLY,
        note="itmtl.toml over 100 seeds (the paper's run count was lost)",
    ),
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
            "Fig. 4",
            "GNA-ESSP attains the mean CRB (distance-independent noise, target around the anchors' centre)",
            "ratio",
            Q("ramezani.localization_essp.rmse_m", statistic="rms"),
            "loc",
            b=Q("ramezani.localization_essp.sqrt_mean_crb_m", statistic="rms"),
            paper=1.0,
            paper_text="on the mean CRB (RMSE / sqrt(mean CRB) = 1)",
            statistic="RMSE over every fix of every seed / sqrt(mean CRB over the same fixes)",
            bound=True,
        ),
        Claim(
            "gna_essp_vs_assp",
            "Fig. 4",
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
            "Fig. 11",
            "EKF-ESSP attains the PCRB over steps 300-500 (sigma_t = 1 ms, start [500, 50, 50] m)",
            "ratio",
            Q("ramezani.tracking_essp.rmse_m", statistic="rms"),
            "track",
            b=Q("ramezani.tracking_essp.sqrt_mean_pcrb_m", statistic="rms"),
            paper=1.0,
            paper_text="on the PCRB (RMSE / sqrt(mean PCRB) = 1)",
            statistic="RMSE over steps 300-500 of every seed's trajectory / sqrt(mean PCRB over the same steps); "
            "the PCRB of each trajectory along its own truth",
            bound=True,
        ),
        Claim(
            "ekf_essp_vs_assp",
            "Fig. 11",
            "EKF-ESSP more accurate than EKF-ASSP (sigma_t = 1 ms, start [500, 50, 50] m)",
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
        note="200 fixes per localization run, one 500-step trajectory per tracking run; 10 seeds each",
    ),
    full=Scale(
        {"loc": "scenarios/ramezani_localization.toml", "track": "scenarios/ramezani_tracking.toml"},
        runs=50,
        runs_by_scenario={"track": 5000},
        note="localization: 50 seeds of 200 fixes (the paper's 10^4 Monte Carlo runs per point); tracking: "
        "5000 trajectories (the paper's 5000 independent Monte Carlo trials)",
    ),
)

# -------------------------------------------------------------------------------------- MSWPF
_MSWPF_T1 = {  # Table 1 (2-D, r_x = 0, Ns = 3): L -> (GW, EW, BW) in m, Improvement of GW over EW in %
    2: (27.05, 31.80, 31.92, 14.9),
    4: (11.38, 13.95, 18.14, 18.4),
    6: (7.312, 9.694, 14.30, 24.6),
    8: (6.265, 8.581, 13.15, 27.0),
}
#: eq 37: at each interval the RMSE over the Monte Carlo runs, averaged over the intervals
_EQ37 = "mswpf.step_error_m"


def _mswpf_q(w: str) -> Quantity:
    return Q(_EQ37, w, statistic="time_mean_rms", label=f"{w.upper()}: eq 37 (m)")


def _mswpf_claims() -> tuple[Claim, ...]:
    out: list[Claim] = []
    stat = "time average over the {n} intervals of the RMSE over runs at each interval (eq 37)"
    for L, (gw, ew, bw, imp) in _MSWPF_T1.items():
        over = (f"nodes.1.params.levels={L}",)
        for w, v in zip(("gw", "ew", "bw"), (gw, ew, bw)):
            out.append(
                Claim(
                    f"t1_{w}_L{L}",
                    "Table 1",
                    f"{w.upper()} average tracking error at L = {L}",
                    "value",
                    _mswpf_q(w),
                    "2d",
                    paper=v,
                    paper_text=f"{v} m (eq 37 over 100 Monte Carlo runs, averaged over time)",
                    statistic=stat.format(n=80),
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
                    _mswpf_q(x),
                    "2d",
                    b=_mswpf_q(y),
                    paper_text=f"{x.upper()} below {y.upper()}",
                    statistic="difference of the eq-37 errors, paired bootstrap over runs",
                    overrides=over,
                )
            )
        out.append(
            Claim(
                f"t1_improvement_L{L}",
                "Table 1",
                f"Improvement of GW over EW at L = {L}",
                "gap_pct",
                _mswpf_q("gw"),
                "2d",
                b=_mswpf_q("ew"),
                of="b",
                paper=imp,
                paper_text=f"{imp} % (100 (EW - GW) / EW of the eq-37 errors)",
                statistic="100 (EW - GW) / EW of the eq-37 errors, paired bootstrap over runs",
                overrides=over,
            )
        )
    for w, v in (("gw", 13.26), ("ew", 17.20)):
        out.append(
            Claim(
                f"t3_{w}",
                "Table 3",
                f"3-D {w.upper()} average tracking error (Ns = 3, L = 8)",
                "value",
                _mswpf_q(w),
                "3d",
                paper=v,
                paper_text=f"{v} m (eq 37)",
                statistic=stat.format(n=60),
            )
        )
    out.append(
        Claim(
            "t3_gw_lt_ew",
            "Table 3",
            "3-D GW < EW (Ns = 3, L = 8)",
            "less",
            _mswpf_q("gw"),
            "3d",
            b=_mswpf_q("ew"),
            paper_text="GW below EW",
            statistic="difference of the eq-37 errors, paired bootstrap over runs",
        )
    )
    out.append(
        Claim(
            "t3_improvement",
            "Table 3",
            "3-D Improvement of GW over EW (Ns = 3, L = 8)",
            "gap_pct",
            _mswpf_q("gw"),
            "3d",
            b=_mswpf_q("ew"),
            of="b",
            paper=22.9,
            paper_text="22.9 % (100 (EW - GW) / EW)",
            statistic="100 (EW - GW) / EW of the eq-37 errors, paired bootstrap over runs",
        )
    )
    return tuple(out)


MSWPF = Paper(
    key="mswpf",
    title="MSWPF (Zhang et al.): MI-weighted multi-sensor particle filter with PCRLB selection",
    doc="docs/mswpf.md",
    readings=(
        Reading(
            "printed",
            "eq 6 as printed (k = 2, S = 5e4), the paper's CV truth q = 1 kept in the field; eq 37's statistic",
        ),
        Reading(
            "former",
            "the former defaults: k = 1 (amplitude as 1/D), truth the straight CV line (q = 0); eq 37's statistic",
            variants={"gw": "gw_former", "ew": "ew_former", "bw": "bw_former"},
        ),
        Reading(
            "printed_pooled",
            "eq 6 as printed; the pooled RMSE (RMS over runs of each run's RMSE over its intervals) instead of eq 37",
            metrics={_EQ37: ("mswpf.rmse_m", "rms")},
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
_SV_TABLES = {  # scenario key -> (table, SVL-PF, LSSVR-PF, ToA-PF) at k = 100, m: one example run each
    "s1": ("Table 2", 2.4971, 3.8613, 4.2943),
    "s2": ("Table 3", 3.4523, 8.2197, 6.5046),
}
_ALSO = 'nodes.0.params.also=["toa_pf", "lssvr_pf", "consensus"]'


def _svlpf_claims() -> tuple[Claim, ...]:
    out: list[Claim] = []
    for sc, (table, sv, ls, toa) in _SV_TABLES.items():
        readings = ("printed", "repaired") if sc == "s1" else ()
        stat = "mean over seeds of eq 32's accumulated error at k = 100, and one run's 95 % prediction interval"
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
                    paper_text=f"{v} m at k = 100 (one example run)",
                    statistic=stat,
                    readings=readings,
                    paper_runs="one",
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

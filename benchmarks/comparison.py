"""Method comparison at the standard of optimizer benchmarking (COCO/BBOB's ``cocopp``, IOHprofiler,
nevergrad): targets and expected running times, ECDFs of runs reaching targets, anytime curves,
Dolan-Moré performance profiles, and paired rank tests with a multiple-comparison correction.

Everything is computed from a campaign folder's ``runs.csv`` and ``traces.csv`` (written by
``magbench compare``) and written beside them as ``comparison/*.csv|md`` and ``figures/*``:

- **targets** (per scenario and trial): in residual RMS relative to the trial's optimum (lsq's answer
  when lsq ran, else the best of all methods) at the factors ``RMS_TARGETS``, and in angle error
  relative to the trial's Cramér-Rao standard deviation at ``ANGLE_TARGETS``;
- **expected running time** (COCO's ERT, "aRT"): evaluations (and seconds) summed over all runs up to
  the target or to their end, divided by the number of runs that reached it; restarts are counted as
  COCO counts them (an unsuccessful run contributes its whole cost);
- **ECDF** of (run, target) pairs reached against evaluations, per scenario and method;
- **anytime curves**: median and inter-quartile band over trials of the best RMS so far / optimum;
- **performance profiles** (Dolan & Moré 2002) across scenarios on the ERT to the 1.01 x optimum target;
- **paired tests**: per scenario, the methods see the same data in each trial, so every pair is compared
  by the Wilcoxon signed-rank test on the final RMS, Holm-corrected over the pairs of that scenario,
  with a win-rate matrix; a warning where trials are too few for the test to reach significance.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd

from magbench.benchmarks.comparison_figures import COMPARISON_KINDS
from magbench.benchmarks.figures import make_figures
from magbench.benchmarks.tables import md_escape, write_output

RMS_TARGETS = (10.0, 2.0, 1.1, 1.01, 1.001)
"""Targets in residual RMS as multiples of the trial's optimum (COCO uses a ladder of precisions)."""
ANGLE_TARGETS = (10.0, 3.0, 1.5)
"""Targets in worst angle error as multiples of the trial's Cramér-Rao standard deviation."""
PROFILE_TARGET = 1.01
"""The RMS target whose ERT the performance profile compares."""
ALPHA = 0.05
"""Family-wise error rate of the Holm-corrected paired tests."""
PRACTICAL_MARGIN = 0.01
"""A difference matters in practice when it exceeds this share of the scenario's optimum RMS (the median over
trials of the best configuration's RMS): "better" needs a significant difference larger than the margin,
"equivalent" a significant difference smaller than it in both directions (two one-sided tests, TOST)."""
MIN_TRIALS_FOR_TESTS = 10
"""Below this many paired trials the signed-rank test has little power (at 5 trials the smallest
two-sided p-value is 0.0625): the tables say so."""
ECDF_POINTS = 60
"""Evaluation budgets (log-spaced) at which ECDFs and anytime curves are tabulated."""


def _ok(runs: pd.DataFrame) -> pd.DataFrame:
    runs = runs.copy()
    runs["error"] = runs["error"].astype(object).fillna("")
    return runs[runs["error"] == ""]


def optimum_per_trial(runs: pd.DataFrame) -> pd.DataFrame:
    """The reference RMS of each (scenario, trial): lsq's answer where lsq ran, else the best answer."""
    ok = _ok(runs)
    best = ok.groupby(["scenario", "trial"])["rms_after_nT"].min().rename("optimum_nT")
    lsq = ok[ok["method"] == "lsq"].groupby(["scenario", "trial"])["rms_after_nT"].min().rename("lsq_nT")
    out = pd.concat([best, lsq], axis=1)
    out["optimum_nT"] = out["lsq_nT"].where(out["lsq_nT"].notna(), out["optimum_nT"])
    return out[["optimum_nT"]].reset_index()


def _trace_of(traces: pd.DataFrame) -> dict:
    """(scenario, configuration, trial) -> (evaluations, best RMS so far) arrays; trial 0 when the
    campaign kept traces of the first trial only."""
    if traces is None or traces.empty:
        return {}
    trial = traces["trial"] if "trial" in traces else pd.Series(0, index=traces.index)
    out = {}
    for key, part in traces.assign(trial=trial).groupby(["scenario", "configuration", "trial"], sort=False):
        order = np.argsort(part["evaluations"].to_numpy(), kind="stable")
        ev = part["evaluations"].to_numpy(dtype=float)[order]
        best = np.sqrt(np.minimum.accumulate(part["best_F"].to_numpy(dtype=float)[order]))
        out[key] = (ev, best)
    return out


def _evaluations_to(trace, target: float) -> float:
    ev, best = trace
    hit = np.flatnonzero(best <= target)
    return float(ev[hit[0]]) if hit.size else math.inf


def hitting_times(runs: pd.DataFrame, traces: pd.DataFrame | None) -> pd.DataFrame:
    """One row per (run, target): evaluations and seconds to reach it (inf when not reached), and what the
    run cost in all.  From the run's trace where there is one; otherwise a run that ends at or below the
    target counts as reaching it at its last evaluation (an upper bound)."""
    ok = _ok(runs).merge(optimum_per_trial(runs), on=["scenario", "trial"], how="left")
    trace_of = _trace_of(traces)
    rows = []
    for r in ok.itertuples(index=False):
        n_ev = float(r.n_evaluations) if pd.notna(r.n_evaluations) else math.nan
        closed = getattr(r, "evaluation_mode", "counted") == "closed-form"
        trace = trace_of.get((r.scenario, r.configuration, r.trial))
        for factor in RMS_TARGETS:
            target = factor * r.optimum_nT
            if trace is not None and not closed:
                ev = _evaluations_to(trace, target)
            else:
                ev = n_ev if r.rms_after_nT <= target * (1 + 1e-12) else math.inf
            reached = math.isfinite(ev)
            seconds = (r.runtime_s * min(ev / n_ev, 1.0) if reached and n_ev > 0 else
                       (r.runtime_s if reached else math.inf))
            rows.append({"scenario": r.scenario, "configuration": r.configuration, "trial": r.trial,
                         "kind": "rms", "target": factor, "evaluations": ev, "seconds": seconds,
                         "cost_evaluations": n_ev, "cost_seconds": r.runtime_s, "closed_form": closed})
        rows += _angle_hits(r, n_ev, closed)
    return pd.DataFrame(rows)


def _angle_hits(r, n_ev: float, closed: bool) -> list[dict]:
    ratios = []
    for a in ("alpha", "beta", "gamma"):
        err, crb = getattr(r, f"{a}_err_rad", math.nan), getattr(r, f"crb_{a}_rad", math.nan)
        if pd.notna(err) and pd.notna(crb) and crb > 0:
            ratios.append(abs(err) / crb)
    if not ratios:
        return []
    worst = max(ratios)
    return [{"scenario": r.scenario, "configuration": r.configuration, "trial": r.trial, "kind": "angle",
             "target": factor, "evaluations": n_ev if worst <= factor else math.inf,
             "seconds": r.runtime_s if worst <= factor else math.inf, "cost_evaluations": n_ev,
             "cost_seconds": r.runtime_s, "closed_form": closed} for factor in ANGLE_TARGETS]


def expected_running_time(hits: pd.DataFrame) -> pd.DataFrame:
    """COCO's ERT per (scenario, configuration, kind, target): the evaluations (seconds) of all runs up to
    the target or to their end, over the number of successes; ``inf`` when no run reached it."""
    rows = []
    for key, part in hits.groupby(["scenario", "configuration", "kind", "target"], sort=False):
        reached = np.isfinite(part["evaluations"].to_numpy(dtype=float))
        spent_ev = np.where(reached, part["evaluations"], part["cost_evaluations"]).astype(float)
        spent_s = np.where(reached, part["seconds"], part["cost_seconds"]).astype(float)
        n_ok = int(reached.sum())
        rows.append(dict(zip(("scenario", "configuration", "kind", "target"), key),
                         n_runs=len(part), n_reached=n_ok, success_rate=n_ok / len(part),
                         ert_evaluations=spent_ev.sum() / n_ok if n_ok else math.inf,
                         ert_seconds=spent_s.sum() / n_ok if n_ok else math.inf,
                         closed_form=bool(part["closed_form"].any())))
    return pd.DataFrame(rows)


def ecdf(hits: pd.DataFrame, budgets: np.ndarray | None = None) -> pd.DataFrame:
    """Fraction of (run, RMS target) pairs reached within each evaluation budget, per scenario and method
    (COCO's runtime ECDF, aggregated over targets)."""
    rms = hits[(hits["kind"] == "rms") & ~hits["closed_form"]]
    if rms.empty:
        return pd.DataFrame(columns=["scenario", "configuration", "evaluations", "fraction"])
    finite = rms["cost_evaluations"].replace([np.inf], np.nan).dropna()
    top = max(float(finite.max()) if len(finite) else 10.0, 10.0)
    budgets = np.unique(np.geomspace(1, top, ECDF_POINTS).round()) if budgets is None else budgets
    rows = []
    for (scenario, conf), part in rms.groupby(["scenario", "configuration"], sort=False):
        ev = part["evaluations"].to_numpy(dtype=float)
        for b in budgets:
            rows.append({"scenario": scenario, "configuration": conf, "evaluations": float(b),
                         "fraction": float(np.mean(ev <= b))})
    return pd.DataFrame(rows)


def anytime(runs: pd.DataFrame, traces: pd.DataFrame | None) -> pd.DataFrame:
    """Median and inter-quartile band over trials of best-so-far RMS / optimum against evaluations."""
    trace_of = _trace_of(traces)
    if not trace_of:
        return pd.DataFrame(columns=["scenario", "configuration", "evaluations", "median", "q25", "q75", "n"])
    opt = optimum_per_trial(runs).set_index(["scenario", "trial"])["optimum_nT"]
    rows = []
    groups: dict = {}
    for (scenario, conf, trial), tr in trace_of.items():
        if (scenario, trial) in opt.index:
            groups.setdefault((scenario, conf), []).append((tr, opt[(scenario, trial)]))
    for (scenario, conf), items in groups.items():
        top = max(tr[0][-1] for tr, _ in items)
        grid = np.unique(np.geomspace(1, max(top, 2.0), ECDF_POINTS).round())
        curves = []
        for (ev, best), optimum in items:
            idx = np.searchsorted(ev, grid, side="right") - 1
            curves.append(np.where(idx >= 0, best[np.clip(idx, 0, None)] / optimum, np.nan))
        stack = np.array(curves)
        with np.errstate(all="ignore"):
            for j, b in enumerate(grid):
                col = stack[:, j][np.isfinite(stack[:, j])]
                if col.size:
                    rows.append({"scenario": scenario, "configuration": conf, "evaluations": float(b),
                                 "median": float(np.median(col)), "q25": float(np.quantile(col, 0.25)),
                                 "q75": float(np.quantile(col, 0.75)), "n": int(col.size)})
    return pd.DataFrame(rows)


def performance_profile(ert: pd.DataFrame, target: float = PROFILE_TARGET) -> pd.DataFrame:
    """Dolan-Moré: for each method, the fraction of scenarios on which its ERT (evaluations) to ``target``
    is within a factor tau of the best method's.  Closed-form methods are left out (no evaluations)."""
    part = ert[(ert["kind"] == "rms") & (ert["target"] == target) & ~ert["closed_form"]]
    if part.empty:
        return pd.DataFrame(columns=["configuration", "tau", "fraction"])
    table = part.pivot_table(index="scenario", columns="configuration", values="ert_evaluations", aggfunc="first")
    best = table.min(axis=1)
    ratio = table.div(best, axis=0).replace([np.nan], np.inf)
    finite = ratio.to_numpy()[np.isfinite(ratio.to_numpy())]
    taus = np.unique(np.concatenate([[1.0], np.geomspace(1.0, max(float(finite.max()) if finite.size else 2.0, 2.0) * 2,
                                                        40)]))
    rows = [{"configuration": conf, "tau": float(t), "fraction": float(np.mean(ratio[conf].to_numpy() <= t))}
            for conf in ratio.columns for t in taus]
    return pd.DataFrame(rows)


def holm(p_values: np.ndarray) -> np.ndarray:
    """Holm's step-down adjusted p-values (family-wise error control)."""
    p = np.asarray(p_values, dtype=float)
    order = np.argsort(p)
    adjusted = np.empty_like(p)
    running = 0.0
    for rank, i in enumerate(order):
        running = max(running, (len(p) - rank) * p[i])
        adjusted[i] = min(running, 1.0)
    return adjusted


EXACT_SIGNED_RANK_N = 50
"""Up to this many paired trials without ties or zeros, the signed-rank test's p-value is exact."""
PERMUTATION_SIGNED_RANK_N = 13
"""Up to this many paired trials with ties or zeros, it is exact over all 2^n sign patterns."""


def signed_rank_p(d: np.ndarray, alternative: str = "two-sided") -> float:
    """p-value of the Wilcoxon signed-rank test of the paired differences ``d`` (Wilcoxon 1945), with zero
    differences split evenly between the positive and negative rank sums ("zsplit"), as
    ``scipy.stats.wilcoxon(d, zero_method="zsplit")`` computes it (SciPy 1.17, ``method="auto"``; the test
    suite checks the two against each other), without importing ``scipy.stats`` (half a second on every
    comparison).  The statistic is the rank sum of the positive differences (average ranks of ``|d|``, half
    the zeros' ranks added); its null distribution is

    - exact (the distribution of a sum of a random subset of 1..n) with no ties and no zeros and n <= 50;
    - exact over the 2^n sign flips when there are ties or zeros and n <= 13 (a value within 100 machine
      epsilons of the observed one counts as equal);
    - otherwise normal, mean n(n+1)/4 and variance (n(n+1)(2n+1) - sum(t^3 - t)/2)/24 over the tie groups
      t (no continuity correction).

    ``alternative``: ``two-sided`` (twice the smaller tail, at most 1), ``greater`` (the positive
    differences rank high) or ``less``."""
    if alternative not in ("two-sided", "greater", "less"):
        raise ValueError(f"alternative must be two-sided, greater or less, not {alternative!r}")
    d = np.asarray(d, dtype=float)
    n = len(d)
    if n == 0:
        return math.nan
    values, inverse, ties = np.unique(np.abs(d), return_inverse=True, return_counts=True)
    ranks = (np.cumsum(ties) - (ties - 1) / 2.0)[inverse]  # average ranks of |d|, 1..n
    zero = d == 0
    half_zeros = float(ranks[zero].sum()) / 2.0
    r_plus = float(ranks[d > 0].sum()) + half_zeros
    tied = bool((ties > 1).any())
    if not tied and not zero.any() and n <= EXACT_SIGNED_RANK_N:
        pmf = np.ones(1)  # the rank sum of a random subset of 1..k, built up k by k
        for k in range(1, n + 1):
            grown = np.zeros(k * (k + 1) // 2 + 1)
            grown[:len(pmf)] = pmf * 0.5
            grown[-len(pmf):] += pmf * 0.5
            pmf = grown
        mean = n * (n + 1) / 4.0

        def cdf(k: int) -> float:
            return float(pmf[:k + 1].sum()) if k <= mean else 1.0 - float(pmf[k + 1:].sum())

        def sf(k: int) -> float:
            return float(pmf[k:].sum()) if k <= mean else 1.0 - float(pmf[:k].sum())

        low, high = cdf(math.ceil(r_plus)), sf(math.floor(r_plus))
    elif n <= PERMUTATION_SIGNED_RANK_N:
        signs = 1 - 2 * ((np.arange(2 ** n)[:, None] >> np.arange(n)) & 1)  # every sign pattern, (2^n, n)
        null = ((signs * d) > 0).astype(float) @ ranks + half_zeros
        gamma = abs(100 * np.finfo(float).eps * r_plus)
        low = float(np.count_nonzero(null <= r_plus + gamma)) / len(null)
        high = float(np.count_nonzero(null >= r_plus - gamma)) / len(null)
    else:
        variance = (n * (n + 1.0) * (2.0 * n + 1.0) - float(np.sum(ties ** 3.0 - ties)) / 2.0) / 24.0
        z = (r_plus - n * (n + 1.0) * 0.25) / math.sqrt(variance) if variance > 0 else math.nan
        low, high = 0.5 * math.erfc(-z / math.sqrt(2.0)), 0.5 * math.erfc(z / math.sqrt(2.0))
    if alternative == "less":
        return low
    if alternative == "greater":
        return high
    return min(1.0, 2.0 * min(low, high))


def paired_tests(runs: pd.DataFrame, metric: str = "rms_after_nT") -> tuple[pd.DataFrame, pd.DataFrame]:
    """Per scenario, every pair of configurations on the same trials: Wilcoxon signed-rank on ``metric``
    (lower is better; ``signed_rank_p``), Holm-corrected within the scenario, and the win rate (ties count
    one half)."""
    tests, wins = [], []
    for scenario, part in _ok(runs).groupby("scenario", sort=False):
        table = part.pivot_table(index="trial", columns="configuration", values=metric, aggfunc="first")
        confs = list(table.columns)
        margin = PRACTICAL_MARGIN * float(np.nanmedian(table.min(axis=1))) if len(table) else math.nan
        pairs = []
        for i, a in enumerate(confs):
            for b in confs:
                both = table[[a, b]].dropna()
                if a != b:
                    x, y = both[a].to_numpy(), both[b].to_numpy()
                    wins.append({"scenario": scenario, "row": a, "column": b, "n": len(both),
                                 "win_rate": float(np.mean((x < y) + 0.5 * (x == y))) if len(both) else math.nan})
            for b in confs[i + 1:]:
                both = table[[a, b]].dropna()
                diff = (both[a] - both[b]).to_numpy()
                p = signed_rank_p(diff) if len(diff) and np.any(diff != 0) else 1.0
                pairs.append({"scenario": scenario, "a": a, "b": b, "n": len(diff), "median_diff": float(np.median(diff))
                              if len(diff) else math.nan, "p": p, "margin_nT": margin,
                              "p_equivalent": _tost(diff, margin)})
        if pairs:
            adjusted = holm(np.array([q["p"] for q in pairs]))
            equivalence = holm(np.array([q["p_equivalent"] for q in pairs]))  # the same family-wise control
            for q, adj, eq in zip(pairs, adjusted, equivalence):
                q["p_holm"] = float(adj)
                q["p_equivalent"] = float(eq)
                q["significant"] = bool(adj < ALPHA)
                practical = q["significant"] and abs(q["median_diff"]) > q["margin_nT"]
                q["better"] = (q["a"] if q["median_diff"] < 0 else q["b"]) if practical else ""
                q["verdict"] = (f"{q['better']} better" if practical else
                                "equivalent" if q["p_equivalent"] < ALPHA else "inconclusive")
                q["warning"] = (f"only {q['n']} paired trials: too few for the test" if q["n"] < MIN_TRIALS_FOR_TESTS
                                else "")
            tests += pairs
    return pd.DataFrame(tests), pd.DataFrame(wins)


def _smallest_holm_p(n: int, pairs: int) -> float:
    """The smallest Holm-adjusted p-value a two-sided exact Wilcoxon signed-rank test of n paired trials can
    give among ``pairs`` comparisons: ``pairs * 2 / 2**n`` (every difference of one sign), at most 1."""
    return min(1.0, pairs * 2.0 / 2.0 ** max(n, 0)) if n > 0 else 1.0


def _tost(diff: np.ndarray, margin: float) -> float:
    """p-value of equivalence within +-margin (two one-sided Wilcoxon tests; the larger of the two)."""
    if len(diff) < 2 or not margin > 0:
        return 1.0
    return max(signed_rank_p(diff + margin, "greater"), signed_rank_p(diff - margin, "less"))


def _md_table(frame: pd.DataFrame, columns: list[tuple[str, str, str]]) -> str:

    head = [h for _, h, _ in columns]
    lines = ["| " + " | ".join(md_escape(h) for h in head) + " |", "|" + "---|" * len(head)]
    for _, r in frame.iterrows():
        cells = []
        for col, _, fmt in columns:
            v = r[col]
            cells.append("∞" if isinstance(v, float) and math.isinf(v) else
                         ("-" if isinstance(v, float) and math.isnan(v) else fmt.format(v)))
        lines.append("| " + " | ".join(md_escape(c) for c in cells) + " |")
    return "\n".join(lines) + "\n"


def write_comparison(campaign_dir, figures: bool = True, formats=("png",), dpi: int = 300, jobs: int = 1) -> list[Path]:
    """Compute everything above for a campaign folder and write comparison/*.csv, comparison.md and, with
    ``figures``, figures/ecdf, figures/anytime and figures/profile (drawn by ``figures.make_figures``, on
    ``jobs`` processes)."""
    d = Path(campaign_dir)
    runs = pd.read_csv(d / "runs.csv", keep_default_na=False, na_values=[""], dtype={"error": str})
    runs["error"] = runs["error"].fillna("")
    traces = pd.read_csv(d / "traces.csv") if (d / "traces.csv").exists() and (d / "traces.csv").stat().st_size else None
    out = d / "comparison"
    out.mkdir(exist_ok=True)
    hits = hitting_times(runs, traces)
    ert = expected_running_time(hits)
    curves = ecdf(hits)
    any_ = anytime(runs, traces)
    profile = performance_profile(ert)
    tests, wins = paired_tests(runs)
    written = []
    for name, frame in (("ert", ert), ("ecdf", curves), ("anytime", any_), ("profile", profile),
                        ("paired_tests", tests), ("win_rate", wins)):
        path = out / f"{name}.csv"
        write_output(path, frame.to_csv(index=False, float_format="%.6g"))
        written.append(path)
    written.append(_write_markdown(d / "comparison.md", runs, ert, tests, wins))
    if figures:

        written += make_figures(d, formats=tuple(formats or ("png",)), dpi=dpi, kinds=COMPARISON_KINDS, jobs=jobs)
    return written


def ert_cell(r) -> str:
    """An ERT for the table: evaluations for a counted method, seconds for a closed-form one, ∞ when no run
    reached the target; the success rate when some runs missed it."""
    if math.isinf(r.ert_evaluations):
        return "∞"
    value = f"{r.ert_seconds * 1e3:.3g} ms" if r.closed_form else f"{r.ert_evaluations:.3g}"
    return value if r.success_rate == 1 else f"{value} ({r.n_reached}/{r.n_runs})"


def _write_markdown(path: Path, runs: pd.DataFrame, ert: pd.DataFrame, tests: pd.DataFrame, wins: pd.DataFrame) -> Path:
    n_trials = runs.groupby("scenario")["trial"].nunique()
    lines = ["# Method comparison", "",
             "Targets: residual RMS within a factor of the trial's optimum (lsq's answer), and worst angle error "
             "within a multiple of the Cramér-Rao standard deviation. ERT: expected running time (COCO), the "
             "evaluations of all runs up to the target or their end over the number of runs that reached it; "
             "∞: no run reached it. Closed-form methods have no evaluations: their ERT is in seconds only.", ""]
    few = [f"{s} ({n} trials)" for s, n in n_trials.items() if n < MIN_TRIALS_FOR_TESTS]
    if few:
        lines += [f"**Warning:** too few trials for the paired tests and ERTs to be firm in: {', '.join(few)} "
                  f"(at least {MIN_TRIALS_FOR_TESTS} are needed).", ""]
    for scenario, part in ert.groupby("scenario", sort=False):
        lines += [f"## {scenario}", "", "### Expected running time to each target", ""]
        part = part.assign(col=np.where(part["kind"] == "rms", "RMS ≤ " + part["target"].map("{:g}".format) + "×",
                                        "angle ≤ " + part["target"].map("{:g}".format) + "σ"),
                           cell=[ert_cell(r) for r in part.itertuples(index=False)])
        order = list(dict.fromkeys(part["configuration"]))
        table = part.pivot_table(index="configuration", columns="col", values="cell", aggfunc="first", sort=False)
        table = table.reindex(order).reset_index()
        cols = [("configuration", "calibrator", "{}")] + [(c, c, "{}") for c in table.columns if c != "configuration"]
        lines += [_md_table(table, cols), ""]
        t = tests[tests["scenario"] == scenario] if len(tests) else tests
        if len(t):
            margin = float(t["margin_nT"].iloc[0])
            lines += ["### Paired Wilcoxon signed-rank tests on the final RMS (Holm-corrected)", "",
                      f"A configuration is *better* only when the difference is significant (Holm, {ALPHA:g}) and "
                      f"larger than the practical margin of {margin:.3g} nT ({100 * PRACTICAL_MARGIN:g} % of this "
                      "scenario's optimum RMS); *equivalent* when two one-sided tests show it within the margin "
                      f"(Holm-corrected too); else *inconclusive*. With {len(t)} pairs and {int(t['n'].min())} "
                      "trials the smallest possible Holm p-value is about "
                      f"{_smallest_holm_p(int(t['n'].min()), len(t)):.2g}, so with few trials even a large "
                      "difference reads *inconclusive*.", "",
                      _md_table(t, [("a", "A", "{}"), ("b", "B", "{}"), ("n", "trials", "{:d}"),
                                    ("median_diff", "median A−B nT", "{:.3g}"), ("p_holm", "p (Holm)", "{:.3g}"),
                                    ("margin_nT", "margin nT", "{:.3g}"), ("p_equivalent", "p (equivalence)", "{:.3g}"),
                                    ("verdict", "verdict", "{}"), ("warning", "note", "{}")]), ""]
        w = wins[wins["scenario"] == scenario] if len(wins) else wins
        if len(w):
            order = list(dict.fromkeys(part["configuration"]))
            matrix = w.pivot_table(index="row", columns="column", values="win_rate", aggfunc="first")
            matrix = matrix.reindex(index=[o for o in order if o in matrix.index],
                                    columns=[o for o in order if o in matrix.columns]).reset_index()
            cols = [("row", "row beats column", "{}")] + [(c, c, "{:.2f}") for c in matrix.columns if c != "row"]
            lines += ["### Win rate (fraction of trials where the row's RMS is lower)", "", _md_table(matrix, cols), ""]
    write_output(path, "\n".join(lines) + "\n")
    return path

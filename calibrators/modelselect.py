"""Model ``auto``: the simplest model the data need (MATLAB magcal's ``auto``, by held-out residual).

Every candidate model the calibrator supports (``offset``, ``angles``, ``diag``, ``nine``) is fitted by
least squares (``lsq``) on the whole record and judged on two things:

- **identifiability**: that full fit's acceptance checks (Cramér-Rao deviation of every parameter within
  its tolerance, the offset's profile likelihood, the physical range, and a residual not far above the
  noise estimated independently of the fit), and more distinct attitudes than parameters by
  ``SPARE_ATTITUDES`` (repeated readings of one attitude are not coverage: three attitudes fit a
  three-parameter model exactly, whatever the sensor).  A model the data do not determine (``nine`` on a
  level turntable, say) is not eligible;
- **held-out residual**: k-fold cross-validation (``folds``, 5; points shuffled with the seed): each fold's
  residuals come from the model fitted on the other folds, so a model gains only by what generalises.

The best is the candidate of least held-out mean square, eligible or not.  The choice is the *simplest*
eligible model (fewest parameters; among equals, the lower held-out residual) that is within noise of the
best: its
held-out squared residuals, paired point by point with the best model's, exceed them on average by no
more than ``Z_WITHIN_NOISE`` standard errors of that mean difference (a paired test), or by less than
``REL_WITHIN_NOISE`` of the best's mean square.  The calibrator then fits the chosen model; the result's
``model_choice`` lists the candidates (held-out RMS, eligibility, rejections) and says why.  When the best
is not eligible and a simpler eligible model is within noise of it, that fallback is stated in the
result's ``warnings`` and in ``model_choice["fallback"]``.  When no eligible model is within noise of the
best (or none is eligible), the calibration is rejected with the reason: a simpler model would leave
structure the data show, and the richer one is not determined.
"""
from __future__ import annotations

import sys
from dataclasses import replace

import numpy as np

from magbench.errors import InputError
from magbench.numerics import BRUTE_NEAREST_ROWS, NEAREST_BLOCK_ELEMENTS, lm_normal, squared_distances
from magbench.simulate.dataset import Dataset
from magbench.simulate.sensor import MODELS, PARAM_NAMES

from .acceptance import REPEAT_FRACTION, SPARE_ATTITUDES  # a candidate's distinct attitudes, as every answer's
from .base import MODEL_CHOOSER, data_problem
from .core.objective import ScalarObjective
from .core.problem import PHYSICAL_BOX, search_bounds
from .methods.lsq import LeastSquares

FOLDS = 5
Z_WITHIN_NOISE = 2.0
"""A simpler model is 'within noise' of the best when its held-out squared residuals exceed the best's by
less than this many standard errors of the paired mean difference."""
REL_WITHIN_NOISE = 1e-3
"""... or by less than this fraction of the best's held-out mean square."""
IDENTIFIABILITY_WORDS = ("not determined", "outside the physical range", "ended on the search bound",
                         "times the noise estimated independently")


def distinct_attitudes(raw_nT: np.ndarray, field_nT: float) -> int:
    """The number of distinct attitudes: groups of readings linked by distances of at most ``REPEAT_FRACTION`` of
    the field (connected components).  Up to BRUTE_NEAREST_ROWS readings while SciPy's spatial module is not imported
    (a one-off ``calibrate --model auto``: that import and scipy.sparse's graph module cost it 0.2-0.5 s), every pair
    is compared (``_linked_groups``: on this project's host 1 ms at 300 readings, 0.04-0.13 s at 1500, the slowest a
    slow path's chain of readings); above, or once it is imported, a k-d tree finds the pairs and scipy.sparse.csgraph
    the components.  The same count either way (tests/test_modelselect.py)."""
    n = len(raw_nT)
    radius = REPEAT_FRACTION * field_nT
    if n <= BRUTE_NEAREST_ROWS and "scipy.spatial" not in sys.modules:
        return _linked_groups(np.asarray(raw_nT, dtype=float), radius)
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    pairs = cKDTree(raw_nT).query_pairs(radius, output_type="ndarray")
    if len(pairs) == 0:
        return n
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    return int(connected_components(graph, directed=False)[0])


def _linked_groups(points: np.ndarray, radius: float) -> int:
    """The connected components of the readings linked at distances of at most ``radius``, by comparing pairs: the
    readings with no other within it are one attitude each (found in blocks of NEAREST_BLOCK_ELEMENTS pairs), the
    others grouped by a breadth-first search among themselves (each step compares the step's new readings with the
    ones not reached yet: held attitudes, a turntable's positions, take a step or two each)."""
    n = len(points)
    if n < 2:
        return n
    limit = radius * radius
    linked = np.zeros(n, dtype=bool)
    step = max(1, NEAREST_BLOCK_ELEMENTS // n)
    for start in range(0, n, step):
        d2 = squared_distances(points[start:start + step], points)
        near = d2 <= limit
        rows = np.arange(near.shape[0])
        near[rows, rows + start] = False  # a reading and itself are no pair
        linked[start:start + step] = near.any(axis=1)
    rest = points[linked]
    groups = n - len(rest)
    reached = np.zeros(len(rest), dtype=bool)
    for seed in range(len(rest)):
        if reached[seed]:
            continue
        groups += 1
        reached[seed] = True
        frontier = np.array([seed])
        while frontier.size:
            todo = np.flatnonzero(~reached)
            if not todo.size:
                break
            hit = np.zeros(len(todo), dtype=bool)
            width = max(1, NEAREST_BLOCK_ELEMENTS // len(todo))
            for start in range(0, len(frontier), width):
                hit |= (squared_distances(rest[frontier[start:start + width]], rest[todo]) <= limit).any(axis=0)
            frontier = todo[hit]
            reached[frontier] = True
    return groups


def _refit(raw: np.ndarray, f_ref: np.ndarray, model: str, x_start: np.ndarray, box) -> np.ndarray:
    obj = ScalarObjective(raw, f_ref, model)
    lo, hi = box
    start = np.clip(x_start, lo + 1e-9 * (hi - lo), hi - 1e-9 * (hi - lo))
    with np.errstate(all="ignore"):
        x, _, _ = lm_normal(obj.normal_equations, start, lo, hi, tol=1e-12, max_iter=100)
    return x


def held_out_residuals(dataset: Dataset, model: str, x_full: np.ndarray, folds: int = FOLDS,
                       seed: int | None = 0) -> np.ndarray:
    """Residual of every point under the model fitted without its fold (k-fold, shuffled by ``seed``)."""
    n = len(dataset)
    order = np.random.default_rng(seed).permutation(n)
    out = np.empty(n)
    box = search_bounds(model, dataset.f_ref_nT, **PHYSICAL_BOX)
    for k in range(folds):
        test = order[k::folds]
        train = np.setdiff1d(order, test, assume_unique=True)
        x = _refit(dataset.raw_nT[train], dataset.f_ref_nT[train], model, x_full, box)
        out[test] = ScalarObjective(dataset.raw_nT[test], dataset.f_ref_nT[test], model).residuals(x)
    return out


def choose_model(dataset: Dataset, candidates=None, folds: int = FOLDS, seed: int | None = 0) -> tuple[str, dict, dict]:
    """Fit every candidate with lsq, cross-validate, choose.  Returns the chosen model, the record of the
    choice (``model_choice``) and the lsq results by model."""
    candidates = [m for m in MODELS if m in (candidates or MODELS)]
    rows, results, sq = [], {}, {}
    field = float(np.median(dataset.f_ref_nT)) if dataset.f_ref_nT is not None else 0.0
    distinct = distinct_attitudes(dataset.raw_nT, field) if field > 0 else len(dataset)
    for model in candidates:
        row = {"model": model, "n_params": len(PARAM_NAMES[model])}
        try:
            res = LeastSquares(model=model, seed=seed).fit(dataset)
        except InputError as exc:
            row.update(eligible=False, rms_heldout_nT=None, rms_fit_nT=None, rejections=[str(exc)])
            rows.append(row)
            continue
        results[model] = res
        unidentified = [r for r in res.rejections if any(w in r for w in IDENTIFIABILITY_WORDS)]
        if distinct < row["n_params"] + SPARE_ATTITUDES:
            unidentified.insert(0, f"{model} is not determined by these data: {distinct} distinct attitude(s) for "
                                   f"{row['n_params']} parameters (it needs {row['n_params'] + SPARE_ATTITUDES}; "
                                   "repeated readings of one attitude are not coverage)")
        e = held_out_residuals(dataset, model, res.x, folds=min(folds, len(dataset)), seed=seed)
        sq[model] = e * e
        row.update(eligible=not unidentified, rms_heldout_nT=float(np.sqrt(np.mean(e * e))),
                   rms_fit_nT=res.rms_after_nT, rejections=unidentified + [r for r in res.rejections
                                                                          if r not in unidentified])
        rows.append(row)
    fitted = [r for r in rows if r["model"] in sq]
    if not fitted:
        reasons = [r["rejections"][0] if r["rejections"] else "no fit" for r in rows]
        if len(set(reasons)) == 1 and reasons[0] != "no fit":  # one cause for every model (no reference, ...): said once
            raise InputError(reasons[0])
        why = "; ".join(f"{r['model']}: {reason}" for r, reason in zip(rows, reasons))
        raise InputError(f"model auto: no candidate model could be fitted to these data ({why})")
    best = min(fitted, key=lambda r: r["rms_heldout_nT"])
    for r in rows:
        if r["model"] not in sq:
            continue
        d = sq[r["model"]] - sq[best["model"]]
        se = float(np.std(d, ddof=1) / np.sqrt(len(d))) if len(d) > 1 else 0.0
        excess = float(np.mean(d))
        r["excess_ms_nT2"] = excess
        r["excess_se_nT2"] = se
        r["within_noise"] = bool(excess <= Z_WITHIN_NOISE * se or excess <= REL_WITHIN_NOISE * float(np.mean(sq[best["model"]])))
    ordered = sorted((r for r in fitted if r["eligible"]), key=lambda r: (r["n_params"], r["rms_heldout_nT"]))
    chosen = next((r for r in ordered if r["within_noise"]), None)
    record = {"requested": "auto", "folds": folds, "distinct_attitudes": distinct,
              "criterion": (f"simplest identifiable model whose {folds}-fold held-out mean square is within "
                            f"{Z_WITHIN_NOISE:g} paired standard errors of the best"),
              "candidates": rows}
    if chosen is None:
        why = "; ".join(f"{r['model']}: {r['rejections'][0] if r['rejections'] else 'not identifiable'}"
                        for r in rows if not r["eligible"])
        worse = [r["model"] for r in ordered]
        lead = (f"the identifiable model(s) {', '.join(worse)} leave significantly more residual than {best['model']} "
                f"({best['rms_heldout_nT']:.4g} nT held out), which these data do not determine" if worse else
                "no candidate model is determined by these data")
        record.update(chosen=best["model"], accepted=False, reason=f"{lead} ({why})")
        return best["model"], record, results
    record.update(chosen=chosen["model"], reason=_reason(chosen, best, rows, folds))
    if not best["eligible"] and best is not chosen:
        cause = best["rejections"][0] if best["rejections"] else "not identifiable"
        record["fallback"] = {"from": best["model"], "to": chosen["model"], "why": cause}
        record["warning"] = (f"model auto fell back from {best['model']} ({best['rms_heldout_nT']:.4g} nT held out) to "
                             f"the simpler {chosen['model']} ({chosen['rms_heldout_nT']:.4g} nT, within noise of it): "
                             f"{cause}")
    return chosen["model"], record, results


def _reason(chosen: dict, best: dict, rows: list[dict], folds: int) -> str:
    parts = [f"{chosen['model']} ({chosen['n_params']} parameters) has a held-out RMS of "
             f"{chosen['rms_heldout_nT']:.4g} nT"]
    if chosen is best:
        parts[0] += ", the lowest of the identifiable models"
    else:
        parts[0] += (f", within noise of the best ({best['model']}, {best['rms_heldout_nT']:.4g} nT: mean squared "
                     f"difference {chosen['excess_ms_nT2']:.3g} +- {chosen['excess_se_nT2']:.3g} nT²)")
    for r in rows:
        if r is chosen:
            continue
        cause = r["rejections"][0] if r["rejections"] else "not identifiable"
        if r.get("rms_heldout_nT") is None:
            parts.append(f"{r['model']} was refused ({cause})")
        elif r["n_params"] > chosen["n_params"] and r["rms_heldout_nT"] >= best["rms_heldout_nT"]:
            parts.append(f"{r['model']} adds parameters without a gain ({r['rms_heldout_nT']:.4g} nT held out)")
        elif not r["within_noise"] and r["rms_heldout_nT"] > best["rms_heldout_nT"]:
            parts.append(f"{r['model']} is significantly worse ({r['rms_heldout_nT']:.4g} nT held out)")
        elif not r["eligible"]:
            fits_better = r["rms_heldout_nT"] < chosen["rms_heldout_nT"] and not r["within_noise"]
            better = " although it fits better" if fits_better else ""
            parts.append(f"{r['model']} ({r['rms_heldout_nT']:.4g} nT held out) is not determined by these data{better} "
                         f"({cause})")
        elif r["n_params"] > chosen["n_params"]:
            parts.append(f"{r['model']} adds parameters without a significant gain ({r['rms_heldout_nT']:.4g} nT "
                         "held out)")
        else:
            parts.append(f"{r['model']} is as simple and within noise, with a higher held-out RMS "
                         f"({r['rms_heldout_nT']:.4g} nT)")
    return "; ".join(parts) + f" ({folds}-fold cross-validation)"


def fit_auto(calibrator, dataset: Dataset):
    """``calibrator.fit`` with ``model="auto"``: choose among the models it supports, then fit that one."""
    candidates = [m for m in MODELS if m in type(calibrator).supported_models]
    if not candidates:
        raise InputError(f"{calibrator.name} supports no model that auto can choose from")
    bad = data_problem(dataset)  # before any candidate's numbers (a row of 1e154 had broken SciPy's tree)
    if bad:
        raise InputError(bad)
    model, record, results = choose_model(dataset, candidates, seed=calibrator.seed)
    chosen = calibrator.set_params(model=model)
    if type(calibrator).name == "lsq" and model in results and results[model].hyperparameters == chosen.get_params():
        result = results[model]
    else:
        result = chosen._fit_dataset(dataset)
    if record.get("accepted") is False:
        return replace(result, model_choice=record, accepted=False,
                       rejections=(f"model auto: {record['reason']}",) + tuple(result.rejections))
    if "warning" in record:
        return replace(result, model_choice=record, warnings=tuple(result.warnings) + (record["warning"],))
    return replace(result, model_choice=record)


MODEL_CHOOSER[:] = [fit_auto]

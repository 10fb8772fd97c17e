"""``results/claims.md``: one row per headline claim of every seed paper, with our reproduction and a
verdict (reproduced / partly / not), each number computed here or read from the other results files
that ``magbench reproduce`` writes (campaign, quality, diagnosis).
"""
from __future__ import annotations

import json
from importlib import resources
from pathlib import Path

import numpy as np
import pandas as pd

from magbench.benchmarks.gradiometer import run_gradiometer
from magbench.benchmarks.metrics import heading_error_deg
from magbench.calibrators import make
from magbench.errors import InputError
from magbench.paper import RESOLUTION_RAD
from magbench.simulate import simulate
from magbench.simulate.effects import OutlierEffect
from magbench.simulate.scenarios import get_scenario


def paper_table2() -> pd.DataFrame:
    """Seed 000's Table 2 as shipped in simulate/data (provenance beside it)."""
    with resources.files("magbench.simulate").joinpath("data/lu2014_table2.csv").open("r", encoding="utf-8") as fh:
        return pd.read_csv(fh, comment="#")


def ellipse2d_heading_error_deg(data) -> float:
    """Seed 004's comparison method: a 2-D ellipse fit of the horizontal readings (x, y) as if the vehicle
    were level; heading from the whitened (x, y) without tilt compensation, against the true heading."""
    from scipy.spatial.transform import Rotation

    raw = np.asarray(data.raw_nT)
    x, y = raw[:, 0], raw[:, 1]
    design = np.column_stack([x * x, x * y, y * y, x, y, np.ones_like(x)])
    scale = np.abs(design).max(axis=0)
    coef = np.linalg.svd(design / scale)[2][-1] / scale  # algebraic conic fit, |theta| = 1
    a, b, c, d, e, f = coef
    q = np.array([[a, b / 2], [b / 2, c]])
    if np.trace(q) < 0:
        q, d, e, f = -q, -d, -e, -f
    centre = -np.linalg.solve(q, np.array([d, e]) / 2)
    w, v = np.linalg.eigh(q)
    whiten = v @ np.diag(np.sqrt(np.maximum(w, 1e-300))) @ v.T  # symmetric: no rotation added
    h = (raw[:, :2] - centre) @ whiten.T
    est = np.arctan2(h[:, 1], h[:, 0])
    truth = data.truth
    b_body_true = Rotation.from_quat(truth.attitude_quat).apply(np.tile(truth.field_ned_nT, (len(raw), 1)),
                                                               inverse=True)
    ref = np.arctan2(b_body_true[:, 1], b_body_true[:, 0])
    err = np.angle(np.exp(1j * (est - ref)))
    err -= np.angle(np.mean(np.exp(1j * err)))  # a constant heading offset is a mounting alignment
    return float(np.degrees(np.sqrt(np.mean(err**2))))


PAPER_RANSAC_EPSILON_SIGMA = 1.0
"""Seed 003's inlier threshold: one standard deviation of the plain fit's residual (the text's setting)."""


def ransac_experiment(n_seeds: int = 30, epsilon_sigma: float = PAPER_RANSAC_EPSILON_SIGMA) -> dict:
    """Seed 003's simulation: 200 points, 50,000 nT, 10 % of the points with 500 nT noise (the rest
    1 nT: the paper does not say), full-sphere attitudes; parameter errors of the plain ellipsoid fit
    against RANSAC with the inlier threshold ``epsilon_sigma`` (the paper's 1 sigma by default)."""
    from dataclasses import replace


    base = get_scenario("sphere9")
    scenario = replace(base, n_points=200, sensor=replace(base.sensor, noise_nT=1.0)).with_effects(
        OutlierEffect(fraction=0.10, amplitude_nT=500.0), name="seed003")
    errs: dict[str, list] = {"ellipsoid": [], "ransac": []}
    for seed in range(n_seeds):
        data = scenario.build(seed)
        t = data.truth.params
        for m in errs:
            params = {"epsilon_sigma": epsilon_sigma} if m == "ransac" else {}
            p = make(m, seed=seed, **params).fit(data).params
            errs[m].append([np.max(np.abs(np.subtract(p.offset_nT, t.offset_nT))),
                            np.max(np.abs(np.subtract(p.scale, t.scale))),
                            np.max(np.abs(np.subtract([p.alpha_rad, p.beta_rad, p.gamma_rad],
                                                      [t.alpha_rad, t.beta_rad, t.gamma_rad])))])
    med = {m: np.median(np.array(v), axis=0) for m, v in errs.items()}
    ratio = med["ellipsoid"] / med["ransac"]
    return {"n_seeds": n_seeds, "epsilon_sigma": epsilon_sigma,
            "median_offset_err_nT": {m: float(v[0]) for m, v in med.items()},
            "median_scale_err": {m: float(v[1]) for m, v in med.items()},
            "median_angle_err_rad": {m: float(v[2]) for m, v in med.items()},
            "improvement_offset": float(ratio[0]), "improvement_scale": float(ratio[1]),
            "improvement_angles": float(ratio[2])}


def vehicle_experiment(n_seeds: int = 30) -> dict:
    """Seed 004's regime (scenario vehicle9n): TLS and TTLS on the paper's formulation, heading errors
    against a 2-D ellipse fit, the 3-D ellipsoid fit and lsq."""
    out: dict[str, list] = {m: [] for m in ("tls", "ttls", "ellipsoid", "lsq")}
    out["ellipse2d"] = []
    conds, ks, fails = [], [], {m: 0 for m in ("tls", "ttls", "ellipsoid", "lsq")}
    for seed in range(n_seeds):
        data = get_scenario("vehicle9n").build(seed)
        for m in ("tls", "ttls", "ellipsoid", "lsq"):
            try:
                res = make(m, seed=seed).fit(data)
            except InputError:
                fails[m] += 1
                continue
            out[m].append(heading_error_deg(res.params, data))
            if m == "ttls":
                conds.append(res.extra["condition_number_A"])
                ks.append(res.extra["truncation"])
        out["ellipse2d"].append(ellipse2d_heading_error_deg(data))
    return {"n_seeds": n_seeds, "median_heading_err_deg": {m: (float(np.median(v)) if v else None) for m, v in out.items()},
            "failures": fails, "median_condition_number_A": float(np.median(conds)) if conds else None,
            "truncation_levels": {int(k): ks.count(k) for k in sorted(set(ks))}}


def premature_convergence(n_seeds: int = 20) -> dict:
    """When the paper's AGA population collapses: the first generation whose mean fitness is 99 % of the
    best, and the last generation that improved the best of all generations (lu2014, seeds 0..n-1)."""

    gens, last = [], []
    for seed in range(n_seeds):
        res = make("aga", model="angles", seed=seed).fit(simulate("lu2014", seed))
        best, mean = np.array(res.extra["best_fitness"]), np.array(res.extra["mean_fitness"])
        gens.append(int(np.argmax(mean >= 0.99 * best)) + 1)
        running = np.maximum.accumulate(best)
        last.append(int(np.flatnonzero(np.diff(running) > 0)[-1]) + 2 if np.any(np.diff(running) > 0) else 1)
    return {"n_seeds": n_seeds, "median_generation": float(np.median(gens)),
            "median_last_improvement": float(np.median(last))}


def _table2_row(t2: dict) -> str:
    """Seed 000's Table 2 row, from ``results/diagnosis/lu2014_table2.json`` (``diagnose`` on both series)."""
    h = t2["localization"]["heading_harmonics"]
    geo = t2.get("geometry", {})
    fit = geo.get("fitted", {})
    eff = {e["name"]: e for e in t2["effects"]}
    significant = [e["name"] for e in t2["effects"] if e["significant"]]
    causes = geo.get("harmonic_causes", {}).get("2_per_rev", [])
    cannot = geo.get("cannot_tell_apart", [])
    can = geo.get("can_tell_apart", [])
    scale_alone = "scale" in significant and not any("scale" in pair for pair in cannot)
    if not significant:
        verdict = "not"
    elif scale_alone and "+unexplained" not in t2["verdict"]:
        verdict = "reproduced"
    else:
        verdict = "partly"
    ours = (f"magbench diagnose on both Table 2 series: after calibration {h['2_per_rev_nT']:.0f} nT at 2 cycles/rev, "
            f"{h['1_per_rev_nT']:.0f} nT at 1 (noise floor {t2['noise_floor_nT']:.1f} nT); verdict "
            f"`{t2['verdict']}`")
    if "scale" in eff:
        ours += f", the scale effect removes {eff['scale']['shrink_pct']:.0f} % of the gap on held-out headings"
    if geo:
        ours += (f". Fitted geometry: mounting tilt {np.degrees(fit.get('mount_tilt_x_rad', np.nan)):.1f} / "
                 f"{np.degrees(fit.get('mount_tilt_y_rad', np.nan)):.1f} deg, axis-to-field elevation "
                 f"{np.degrees(fit.get('axis_to_field_elevation_rad', np.nan)):.1f} deg, scales "
                 f"{fit.get('kx', np.nan):.3f}/{fit.get('ky', np.nan):.3f}/{fit.get('kz', np.nan):.3f} "
                 f"({geo['identifiable_combinations']} of {geo['n_geometry_parameters']} numbers fixed by the data); "
                 f"the simulator with it reproduces 'before' ({geo['rms_before_nT']:.0f} nT RMS) to "
                 f"{geo['rms_misfit_before_nT']:.1f} nT and 'after' ({geo['rms_after_nT']:.1f} nT) to "
                 f"{geo['rms_misfit_after_nT']:.1f} nT")
    ours += " (results/diagnosis)"
    why = (f"two cycles per revolution is shared by {', '.join(causes) or 'no listed cause'}; the series cannot "
           f"tell apart {'; '.join(cannot) or 'none of them'}, and can tell apart {'; '.join(can) or 'none'}")
    if "field_drift" in eff and not eff["field_drift"]["significant"]:
        why += f"; field drift removes {eff['field_drift']['shrink_pct']:.0f} % (not significant)"
    return _row("000", "The ~50 nT left after calibration comes from effects the 3-angle model omits: scale "
                "mismatch, zero drift, field variation, temperature (section 3)", ours, verdict, why)


PAPERS = {"000": "Lu et al. 2014", "001": "Jin, Zhuang & Wang 2024",
          "002": "the real-coded GA paper on three-component fluxgates (no author in our copy)",
          "003": "Luo et al. (RANSAC ellipsoid fit)", "004": "Zhang et al. (TTLS, L-curve)"}
"""The five source papers by author and year as far as our copies give them (``../shared/seeds`` 000-004)."""


def _row(paper, claim, ours, verdict, why):
    number, _, note = paper.partition(" ")
    return f"| {PAPERS.get(number, number)}{' ' + note if note else ''} | {claim} | {ours} | **{verdict}** | {why} |"


def write_claims(out: Path) -> Path:
    """results/claims.md: one row per headline claim of every seed paper, each verdict computed from
    the numbers beside it (the reproduce outputs in ``out`` and the experiments below)."""
    rows = _seed000_rows(out) + _seed001_rows(out) + _seed002_rows(out) + _seed003_rows(out) + _seed004_rows(out)
    text = ["# Headline claims of the reproduced papers and our reproduction", "",
            "Made by `magbench reproduce`. Verdicts: **reproduced** (the claim holds in our reproduction), **partly** "
            "(holds with a qualification), **not** (our reproduction contradicts it).", "",
            "| paper | claim | our reproduction | verdict | why |", "|---|---|---|---|---|", *rows]
    path = out / "claims.md"
    path.write_text("\n".join(text) + "\n", encoding="utf-8")
    return path


def _share_verdict(share: float) -> str:
    """A claim that something always happens, judged on the share of seeds where it does."""
    return "reproduced" if share >= 0.9 else ("partly" if share >= 0.5 else "not")


def _seed000_rows(out: Path) -> list[str]:
    q = pd.read_csv(out / "quality.csv", keep_default_na=False, na_values=[""])
    lu = q[q["study"] == "lu2014_angles"]
    cols = ["alpha_err_rad", "beta_err_rad", "gamma_err_rad"]
    aga_err = np.abs(lu[lu["method"] == "aga"][cols].to_numpy())
    lm_err = np.abs(lu[lu["method"] == "aga-lm"][cols].to_numpy())
    table = _table2_rms()
    text_matches = abs(table[0] - 411.82) < 1.0 and abs(table[1] - 49.38) < 1.0
    rows = [_row("000", "Calibration reduces the FGM-2000 error by 88.1 % (411.82 -> 49.38 nT, "
                 "section 3 text)", f"the paper's own Table 2 gives {table[0]:.2f} -> {table[1]:.2f} nT "
                 f"({100 * (1 - table[1] / table[0]):.1f} %); on simulated lu2014 the angles alone, once recovered, leave "
                 "only the noise (results/lu2014_tables.md)", "reproduced" if text_matches else "partly",
                 "a large reduction is real, but the text's numbers do not follow from its table"
                 if not text_matches else "the table's rows give the text's numbers")]
    share = float((aga_err <= RESOLUTION_RAD).all(axis=1).mean())
    rows.append(_row("000", "The AGA identifies the three non-orthogonality angles (Table 1), precision 0.0002 rad "
                     "(eq. 6)", f"the AGA as specified is within 0.0002 rad on all three angles in {100 * share:.0f} % of "
                     f"{len(aga_err)} seeds (median worst error {np.median(aga_err.max(axis=1)):.2e} rad); aga-lm in "
                     f"{100 * (lm_err <= RESOLUTION_RAD).all(axis=1).mean():.0f} %", _share_verdict(share),
                     "roulette selection without elitism collapses the population; single-bit mutation cannot "
                     "cross Hamming cliffs (results/quality.md)"))
    collapse = premature_convergence()
    early = collapse["median_last_improvement"] < PREMATURE_FRACTION * PAPER_GENERATIONS
    rows.append(_row("000", "Adaptive Pc and Pm keep diversity and avoid premature convergence (section 2.1)",
                     f"on lu2014 the population's mean fitness reaches 99 % of its best by generation "
                     f"{collapse['median_generation']:.0f} (median of {collapse['n_seeds']} seeds) and the best "
                     f"individual stops improving by generation {collapse['median_last_improvement']:.0f} of the paper's "
                     f"{PAPER_GENERATIONS}, far from the optimum (results/quality.md)", "not" if early else "reproduced",
                     "eq. 4-5 give the best individuals the smallest Pm, so a converged population stops exploring"))
    rows.append(_table2_row(json.loads((out / "diagnosis" / "lu2014_table2.json").read_text())))
    return rows


PAPER_GENERATIONS = 1000
"""Seed 000, section 3: the AGA ran 1,000 generations."""
PREMATURE_FRACTION = 0.2
"""The AGA's best individual stopping before this share of the paper's generations is premature convergence."""


def _table2_rms() -> tuple[float, float]:

    t = paper_table2()
    return float(np.sqrt(np.mean(t["err_before"] ** 2))), float(np.sqrt(np.mean(t["err_after"] ** 2)))


def _seed001_rows(out: Path) -> list[str]:
    g = run_gradiometer(seed=0)
    still = run_gradiometer(seed=0, fluctuation_nT=0.0)
    (out / "gradiometer.json").write_text(json.dumps(g, indent=2, default=float) + "\n")
    ell_still = "/".join(f"{x:.2f}" for x in still["gradient_rms_nT"]["ellipsoid"])
    return [_row("001", "Gradient calibration by three 6-gene GAs leaves about 1.85 nT per axis "
                 "under a fluctuating field, where single-sensor ellipsoid fits fail",
                 _gradiometer_text(g) + f"; in a constant field (no fluctuation) the ellipsoid fits leave {ell_still} nT",
                 _gradiometer_verdict(g, still),
                 "the GA's residual is close to the noise floor set by our chosen noise level, and the ellipsoid "
                 "fits fail about as much in a constant field: their failure is the sensors' relative "
                 "misalignment, which a single sensor cannot see, not the fluctuation the paper credits "
                 "(results/gradiometer.json)")]


def _seed002_rows(out: Path) -> list[str]:
    q = pd.read_csv(out / "quality.csv", keep_default_na=False, na_values=[""])
    rga = q[(q["study"] == "sphere9_optimum") & (q["configuration"] == "rga")]["rms_ratio_to_lsq"]
    camp = pd.read_csv(out / "campaign" / "summary.csv")
    rga_val = camp[(camp["configuration"] == "rga") & (camp["scenario"] == "sphere9")]
    val = (f"; held-out RMS {rga_val['median_val_rms_after_nT'].iloc[0]:.2f} nT on a second data set"
           if len(rga_val) and "median_val_rms_after_nT" in rga_val else "")
    return [_row("002", "A real-coded elitist GA finds the 9 parameters and improves the correction, checked on "
                 "a second set of 100 readings", f"rga reaches lsq's optimum on sphere9 (RMS ratio median "
                 f"{rga.median():.5f}, worst {rga.max():.5f}, {len(rga)} seeds){val}",
                 "reproduced" if rga.max() < 1.01 else "partly",
                 "in simulation; the paper's own parameter values are not legible in our copy")]


def _seed003_rows(out: Path) -> list[str]:
    paper_setting = ransac_experiment()
    ours = ransac_experiment(epsilon_sigma=0.25)
    (out / "ransac_seed003.json").write_text(json.dumps({"paper_setting": paper_setting, "ours_0.25_sigma": ours},
                                                        indent=2) + "\n")
    rows = []
    for r, label in ((paper_setting, "the paper's threshold, 1 sigma"), (ours, "our threshold, 0.25 sigma")):
        rows.append(_row("003" + (" (paper's setting)" if r is paper_setting else " (ours, beside it)"),
                         "RANSAC improves offset and scale accuracy by about two orders of magnitude and "
                         "non-orthogonality by one over the plain ellipsoid fit (200 points, 10 % with 500 nT noise)",
                         f"{label}: median errors plain -> RANSAC ({r['n_seeds']} seeds): offsets "
                         f"{r['median_offset_err_nT']['ellipsoid']:.1f} -> {r['median_offset_err_nT']['ransac']:.2f} nT "
                         f"(x{r['improvement_offset']:.0f}), scale {r['median_scale_err']['ellipsoid']:.1e} -> "
                         f"{r['median_scale_err']['ransac']:.1e} (x{r['improvement_scale']:.0f}), angles "
                         f"{r['median_angle_err_rad']['ellipsoid']:.1e} -> {r['median_angle_err_rad']['ransac']:.1e} rad "
                         f"(x{r['improvement_angles']:.0f})", _ransac_verdict(r),
                         "the verdict follows from the gains: two orders means at least 50x on offsets and scale and "
                         "one order at least 5x on the angles; the noise on the other 90 % (1 nT) is ours"))
    return rows


def _seed004_rows(out: Path) -> list[str]:
    v = vehicle_experiment()
    (out / "vehicle_seed004.json").write_text(json.dumps(v, indent=2) + "\n")
    hd = v["median_heading_err_deg"]
    ok = v["failures"]["tls"] > v["n_seeds"] / 2 and v["failures"]["ttls"] < v["n_seeds"] / 5
    fmt = lambda x: "-" if x is None else f"{x:.2f}°"  # noqa: E731
    return [_row("004", "On vehicle data (cond(A) = 1.36e10) TLS diverges and TTLS with the L-curve does not",
                 f"vehicle9n, {v['n_seeds']} seeds: cond(A) median {v['median_condition_number_A']:.2g}; no "
                 f"ellipsoid from TLS in {v['failures']['tls']}, from TTLS in {v['failures']['ttls']} "
                 f"(L-curve levels {v['truncation_levels']})", "reproduced" if ok else "partly",
                 "A and b are the Foster-Elkaim linearization the paper cites; its own are not legible"),
            _row("004", "Heading error about 1.5° after TTLS against 4.5° for an ellipse fit",
                 f"median RMS heading error: TTLS {fmt(hd['ttls'])}, 2-D ellipse fit {fmt(hd['ellipse2d'])}, "
                 f"3-D ellipsoid fit {fmt(hd['ellipsoid'])}, lsq {fmt(hd['lsq'])}", _heading_verdict(hd),
                 "the claim is a threefold advantage of TTLS over the ellipse fit; the verdict follows from our "
                 "ratio (reproduced at 2x or more with TTLS near 1.5°, not below 1.5x); our van pitches and rolls "
                 "within 3° with 20 nT noise, the paper's read off its Fig. 3")]


def _gradiometer_text(g: dict) -> str:
    r = g["gradient_rms_nT"]
    fmt = lambda v: "/".join(f"{x:.2f}" for x in v)  # noqa: E731
    return (f"gradient residual per axis (x/y/z, nT): raw {fmt(r['raw'])}, single-sensor ellipsoid fits "
            f"{fmt(r['ellipsoid'])}, the paper's three 6-gene GAs {fmt(r['ga'])}, noise floor with the true "
            f"parameters {fmt(r['truth'])} ({g['noise_nT']} nT per axis, chosen by us: the paper gives none)")


def _gradiometer_verdict(g: dict, still: dict) -> str:
    """Reproduced only if the GA's residual matches, the ellipsoid fits fail under the fluctuating field
    *and* succeed without it (the paper's cause), and the match does not rest on the noise level we chose
    (the GA well above the noise floor); partly if the numbers match but either of those does not hold."""
    r, s = g["gradient_rms_nT"], still["gradient_rms_nT"]
    ga, ell, floor = np.mean(r["ga"]), np.mean(r["ellipsoid"]), np.mean(r["truth"])
    matches = ga < 2 * 1.85 and ga < 0.1 * ell
    caused_by_fluctuation = np.mean(s["ellipsoid"]) < 0.5 * ell
    beyond_noise = ga > 1.5 * floor
    if not matches:
        return "not"
    return "reproduced" if caused_by_fluctuation and beyond_noise else "partly"


def _ransac_verdict(r: dict) -> str:
    gains = (r["improvement_offset"], r["improvement_scale"], r["improvement_angles"])
    if gains[0] >= 50 and gains[1] >= 50 and gains[2] >= 5:
        return "reproduced"
    return "partly" if min(gains) >= 3 else "not"


def _heading_verdict(hd: dict) -> str:
    ttls, ellipse = hd.get("ttls"), hd.get("ellipse2d")
    if ttls is None or ellipse is None:
        return "not"
    ratio = ellipse / ttls
    if ratio >= 2 and ttls < 2.25:
        return "reproduced"
    return "not" if ratio < 1.5 else "partly"

"""The outputs of a diagnosis besides its JSON: the human table and the residual figure."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from magbench.calibrators import make
from magbench.simulate.dataset import ScalarSeries
from magbench.simulate.sensor import MODELS, PARAM_NAMES, ErrorParams

from .scalar import scalar_residual, together_columns
from .vector import Diagnosis

FIGURE_SIZE_IN = (8, 4.5)
FIGURE_DPI = 200



def _measure_note(result: dict) -> str:
    """'; MAD scale ...' when the remainder was measured robustly, else nothing."""
    measure = result.get("remainder_measure", "mean square")
    return "" if measure == "mean square" else "; " + measure

def _table(result: dict, source: str) -> list[str]:
    of = f", residual {result['residual_of']}" if "residual_of" in result else ""  # a scalar series: which column
    lines = [f"diagnosis of {source} ({result['n_points']} points, base model: {result['base_model']}{of})",
             f"  residual RMS {result['rms_fit_nT']:.3f} nT on the fit, {result['rms_base_nT']:.3f} nT held out; "
             f"noise floor {result['noise_floor_nT']:.3f} nT"]
    if "floor_interval_nT" in result:
        lo, hi = result["floor_interval_nT"]
        lines.append(f"  noise floor interval {lo:.3f} .. {hi:.3f} nT ({result['floor_method']})")
    spectrum = result.get("noise_spectrum") or {}
    if spectrum.get("statement"):
        lines.append(f"  noise over time scales (what the fit with every effect free leaves): {spectrum['statement']}")
    lines += ["", f"  {'effect':<14}{'held-out RMS nT':>16}{'shrink %':>10}{'interval %':>16}{'z':>8}  selected"]
    for e in result["effects"]:
        iv = e.get("shrink_interval_pct")
        ivs = f"{iv[0]:.0f} .. {iv[1]:.0f}" if iv else "-"
        lines.append(f"  {e['name']:<14}{e['rms_heldout_nT']:>16.3f}{e['shrink_pct']:>10.1f}{ivs:>16}{e['z']:>8.1f}  "
                     f"{'yes' if e['significant'] else 'no'}" + ("  (!)" if e.get("shrink_flag") else ""))
    if any(e.get("shrink_flag") for e in result["effects"]):
        lines.append("  (!) " + next(e["shrink_flag"] for e in result["effects"] if e.get("shrink_flag")))
    if "remainder_nT" in result:
        lines.append(f"  remainder after the selected effects: {result['remainder_nT']:.3f} nT "
                     f"(z {result['remainder_z']:.1f}, {'significant' if result['remainder_significant'] else 'not significant'}"
                     f"{_measure_note(result)})")
    if result.get("remainder_beside_named"):
        lines.append(f"  not called unexplained: {result['remainder_beside_named']}")
    if result.get("remainder_extreme"):
        lines.append(f"  an extreme residual: {result['remainder_extreme']['statement']}")
    if result.get("floor_implausible"):
        lines.append(f"  the noise floor is implausible: {result['floor_implausible']}")
    if result.get("clipped_statement"):
        lines.append(f"  clipped readings: {result['clipped_statement']}")
    if result.get("base_fit", "lsq") != "lsq":
        why = (" (spikes pulled the least-squares fit)" if str(result["base_fit"]).startswith("ransac") else
               f" (the calibrators refuse these attitudes: {result['attitude_coverage']})" if "attitude_coverage" in result
               else "")
        lines.append(f"  base fit: {result['base_fit']}{why}")
    if "power" in result:
        lines.append(f"  power: {result['power']['statement']}")
    if result.get("attitude_reason"):
        lines.append(f"  attitude part: {result.get('attitude', 'insufficient_data')}: {result['attitude_reason']}")
    for name, why in result.get("not_tested", {}).items():
        lines.append(f"  not tested: {name}: {why}")
    for name, why in result.get("not_applicable", {}).items():
        lines.append(f"  not applicable: {name}: {why}")
    return lines


def _localization(loc: dict) -> list[str]:
    if not loc:
        return []
    lines = ["", "  where the residual lies:"]
    for k, v in loc.items():
        if isinstance(v, dict) and all(isinstance(x, (int, float)) for x in v.values()):
            lines.append(f"    {k}: " + ", ".join(f"{kk} {vv:.2f}" for kk, vv in v.items()))
        elif isinstance(v, (int, float)):
            lines.append(f"    {k}: {v:.3f}")
    return lines


def time_only_text(result: dict, source: str = "") -> str:
    """The human summary of a fixed sensor's time-only diagnosis."""
    to = result["time_only"]
    dr = to["drift"]
    clock = to.get("span_h") is not None
    span = f"{to['span_h']:.3g} h" if clock else f"{to['span_rows'] + 1} rows"
    rate = (f"{dr['drift_nT_per_h']:.4g} +- {dr['drift_se_nT_per_h']:.2g} nT/h" if clock else
            f"{1000 * dr['drift_nT_per_row']:.4g} +- {1000 * dr['drift_se_nT_per_row']:.2g} nT per 1000 rows")
    lines = [f"diagnosis of {source} ({result['n_points']} points): the attitudes cannot determine a calibration "
             "model, so only the time question is answered",
             f"  |B| - F: {to['constant_nT']:.3f} nT (median), RMS {to['rms_nT']:.3f} nT over {span}",
             f"  drift: {rate} ({'significant' if dr['significant'] else 'not significant'})",
             *([] if clock else [f"  time axis: {to['time_axis']}"]),
             f"  noise floor {to['noise_floor_nT']:.3f} nT ({to['floor_method']})"]
    spectrum = dr.get("noise_spectrum") or {}
    if spectrum.get("statement"):
        lines.append(f"  noise over time scales (what the smooth trend leaves): {spectrum['statement']}")
    if "temperature" in to:
        tc = to["temperature"]
        lines.append(f"  temperature: {tc['temperature_nT_per_C']:.4g} +- {tc['temperature_se_nT_per_C']:.2g} nT/°C "
                     f"beyond a linear drift ({'significant' if tc['significant'] else 'not significant'})")
    direction = to.get("drift_direction") or {}
    if direction.get("why"):
        lines.append(f"  drift direction: {direction['why']}")
    lines += [f"  {'|'.join(c['alternatives'])}: to separate them: {c['separate_by']}" for c in result.get("confounded", [])]
    lines += [f"  time verdict: {result['time_verdict']}; attitude part: insufficient_data ({result['attitude_reason']})",
              f"  verdict: {result['verdict']}"]
    return "\n".join(lines)


def diagnosis_text(result: dict, source: str = "") -> str:
    """The human table of a diagnosis (``magbench diagnose`` without ``--json``)."""
    note = ([f"  time column: {result['time_column']}"] if result.get("time_column") else []) + (
        [f"  reference: {result['reference_ignored']}"] if result.get("reference_ignored") else []) + (
        [f"  input: {result['input_notes']}"] if result.get("input_notes") else [])
    if result.get("kind") == "time_only":
        return time_only_text(result, source) + "".join("\n" + ln for ln in note)
    lines = _table(result, source) + note + _localization(result.get("localization", {}))
    if "resimulation" in result and "skipped" in result["resimulation"]:
        lines += ["", "  " + result["resimulation"]["skipped"]]
    elif "resimulation" in result:
        rs = result["resimulation"]
        lines.append("")
        lines.append(f"  re-simulated: residual RMS {rs['without_effect']['rms_nT']:.3f} nT without the effect, "
                     f"{rs['with_effect']['rms_nT']:.3f} nT with it, observed {rs['observed']['rms_nT']:.3f} nT "
                     f"(remaining gap {rs['remaining_gap_pct']:.1f} %)")
    g = result.get("geometry")
    if g:
        lines += ["", "  both series (harmonics of the error, nT):"]
        for label in ("before", "after"):
            h = result["series"][label]
            lines.append(f"    {label:<7}" + ", ".join(f"{k} {h[f'{k}_per_rev_nT']:.1f}" for k in (1, 2, 3, 4)))
        c = g["change_before_minus_after"]
        t1 = g["table1_angles_only"]
        lines += [f"    change before-after: 1/rev {c['1_per_rev_nT']:.0f} nT, 2/rev {c['2_per_rev_nT']:.0f} nT; Table 1's "
                  f"angles alone on a level turntable give {t1['level_turntable']['1_per_rev_nT']:.0f} and "
                  f"{t1['level_turntable']['2_per_rev_nT']:.0f} nT (at most {t1['max_2_per_rev_nT']:.0f} nT at 2/rev over "
                  f"{t1['random_mountings']} random mountings)",
                  "  fitted geometry and sensor (both series at once):",
                  "    " + ", ".join(f"{k} {v:.4g}" for k, v in g["fitted"].items()),
                  f"    the simulator then reproduces 'before' to {g['rms_misfit_before_nT']:.1f} nT RMS (of "
                  f"{g['rms_before_nT']:.1f}) and 'after' to {g['rms_misfit_after_nT']:.1f} nT RMS (of {g['rms_after_nT']:.1f})",
                  f"    {g['note']}",
                  "  causes sharing a harmonic:"]
        for k, v in g["harmonic_causes"].items():
            lines.append(f"    {k}: {', '.join(v)}")
        lines.append("    cannot be told apart by this series: " + "; ".join(g["cannot_tell_apart"]))
        lines.append("    can be told apart (4/rev companion of the cubic): " + "; ".join(g["can_tell_apart"]))
    if "offset_and_scale_together" in result:
        both = result["offset_and_scale_together"]
        lines.append(f"  offset (1/rev) and scale (2/rev) together: held-out RMS {both['rms_heldout_nT']:.2f} nT "
                     f"(shrink {both['shrink_pct']:.0f} %)")
    lines += _naming_lines(result)
    lines.append("")
    lines.append(f"  verdict: {result['verdict']}")
    if result.get("figure"):
        lines.append(f"  figure: {result['figure']}")
    return "\n".join(lines)


def _naming_lines(result: dict) -> list[str]:
    """Why a selected effect was not named, and the pairs the data cannot tell apart (the naming rule)."""
    naming = result.get("naming") or {}
    lines = [f"    {row['name']}: not named: {row['why']}" for row in naming.get("evidence", []) if not row.get("named")]
    for pair in result.get("confounded", []):
        lines.append(f"    {'|'.join(pair['alternatives'])}: the data cannot tell them apart "
                     f"({pair['evidence']['statement']}); to separate them: {pair['separate_by']}")
    return ["", "  the naming rule:", *lines] if lines else []


def _plot_scalar(ax, series: ScalarSeries) -> str:
    r = scalar_residual(series)
    x = np.asarray(series.heading_deg)
    before = series.extra.get("f_meas_before")
    if before is not None:
        ax.plot(x, np.asarray(before) - np.asarray(series.f_ref_nT), "^-", label="before (raw total field - reference)")
    ax.plot(x, r, "o-", label="after the file's calibration")
    cols = np.column_stack([np.ones(len(x))] + together_columns(np.radians(x)))
    coef, *_ = np.linalg.lstsq(cols, r, rcond=None)
    ax.plot(x, r - cols @ coef, "s-", label="after removing 1 and 2 cycles/rev (offset + scale)")
    return "turntable heading (deg)"


def _time_is_an_index(data) -> bool:
    """True when the file's ``t`` is a sample index rather than seconds: its provenance says so, or it
    is exactly 0, 1, 2, ..."""
    note = " ".join(str(v) for k, v in getattr(data, "meta", {}).items() if k.startswith("t_note")).lower()
    t = np.asarray(data.t_s)
    return "index" in note or (len(t) > 1 and np.array_equal(t, np.arange(len(t), dtype=float)))


def _plot_vector(ax, data, result: dict) -> str:
    degenerate = result.get("attitude_coverage")
    d = Diagnosis(data, result["base_model"] if result["base_model"] in MODELS else "nine", degenerate=degenerate)
    if degenerate is None:
        correct = make("lsq", model=d.base).fit(data).correct
    else:  # the calibrators refuse these attitudes: the diagnosis's own base correction (fitted with the weak prior)
        correct = ErrorParams.from_vector([result["base_params"][k] for k in PARAM_NAMES[d.base]], d.base).correct
    r = np.linalg.norm(correct(np.asarray(data.raw_nT)), axis=1) - np.asarray(data.f_ref_nT)
    if data.heading_deg is not None:
        x, label = np.asarray(data.heading_deg), "heading (deg)"
    elif data.t_s is not None and not _time_is_an_index(data):
        x, label = np.asarray(data.t_s), "time (s)"
    else:  # no heading and no clock: where the reading points in the sensor frame
        b = correct(np.asarray(data.raw_nT))
        x = np.degrees(np.arccos(np.clip(b[:, 2] / np.linalg.norm(b, axis=1), -1.0, 1.0)))
        label = "angle of the corrected field from the sensor's z axis (deg)"
    ax.plot(x, r, ".", ms=2, label=f"base model ({result['base_model']})")
    if result.get("selected"):
        d.run()
        ax.plot(x, d.model_residuals(result["selected"]), ".", ms=2, label="with " + "+".join(result["selected"]))
    return label


def diagnosis_figure(data, result: dict, path) -> None:
    """Residual before and after the selected effects, titled with the file, against a physical axis
    (turntable heading, time in seconds, or the direction of the reading where the file has neither a
    heading nor a real clock), with the noise floor as a grey band."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=FIGURE_SIZE_IN)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(111)
    if result.get("kind") == "time_only":  # a fixed sensor: |B| - F against time
        clock = result["time_only"].get("span_h") is not None  # the answer's own time axis (time_only: its clock)
        t = np.asarray(data.t_s) / 3600.0 if clock else np.arange(len(data))
        ax.plot(t, np.linalg.norm(np.asarray(data.raw_nT), axis=1) - np.asarray(data.f_ref_nT), ".", ms=2)
        ax.set_xlabel("time (h)" if clock else "row")
        ax.set_ylabel(r"$|B| - F$ (nT)")
        ax.set_title("fixed sensor: the time question only")
        fig.tight_layout()
        fig.savefig(path, dpi=FIGURE_DPI)
        return
    floor = result.get("noise_floor_nT")
    if floor is not None and np.isfinite(floor):
        lo, hi = (result.get("floor_interval_nT") or [floor, floor])[:2]
        ax.axhspan(-floor, floor, color="0.85", zorder=0,
                   label=f"noise floor ±{floor:.3g} nT (95 % interval {lo:.3g}..{hi:.3g})")
    label = _plot_scalar(ax, data) if isinstance(data, ScalarSeries) else _plot_vector(ax, data, result)
    ax.axhline(0.0, color="k", lw=0.8)
    ax.set_xlabel(label)
    ax.set_ylabel("total-field residual (nT)")
    source = Path(str(getattr(data, "meta", {}).get("source_file", "") or "")).name or "data"
    left = [f"{result[key]} {what} left out" for key, what in (("clipped_rows_left_out", "clipped readings"),
                                                               ("held_rows_left_out", "held rows")) if result.get(key)]
    ax.set_title(f"{source}: verdict {result['verdict']}" + (f" ({', '.join(left)})" if left else ""), fontsize=10)
    ax.legend(loc="upper right", fontsize=7)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=FIGURE_DPI, metadata={"Software": None} if str(path).lower().endswith(".png") else None)

"""Campaign tables: the runs as a tidy CSV, summaries (median, inter-quartile range, success rate,
efficiency against the Cramér-Rao bound) in CSV, Markdown and LaTeX, and the manifest."""
from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from magbench.benchmarks.metrics import evaluations_label
from magbench.paper import ARCSEC_PER_RAD
from magbench.safeio import atomic_write

if TYPE_CHECKING:  # pandas is imported where it is used: a campaign's workers import this module without it
    import pandas as pd


ANGLES = ("alpha", "beta", "gamma")
FLOAT_FORMAT = "%.10g"


def _iqr(v: pd.Series) -> float:
    v = v.dropna()
    return float(v.quantile(0.75) - v.quantile(0.25)) if len(v) else np.nan


def successful(part: pd.DataFrame) -> pd.DataFrame:
    """The runs without an error whose calibrator reported success: what the medians are taken over."""
    import pandas as pd

    return part[(part["error"] == "") & part.get("success", pd.Series(True, index=part.index)).fillna(False).astype(bool)]


def summarize(runs: pd.DataFrame) -> pd.DataFrame:
    """One row per (scenario, configuration), in the order they appear in ``runs``."""
    import pandas as pd

    out = []
    for (scenario, conf), part in runs.groupby(["scenario", "configuration"], sort=False):
        ok = successful(part)
        modes = part["evaluation_mode"].dropna() if "evaluation_mode" in part else pd.Series(dtype=object)
        row = {"scenario": scenario, "configuration": conf, "model": part["model"].iloc[0], "n_runs": len(part),
               "evaluation_mode": modes.iloc[0] if len(modes) else "counted",
               "n_failed": int((part["error"] != "").sum()), "success_rate": len(ok) / len(part)}
        if "accepted" in part:
            accepted = part["accepted"].astype("boolean").fillna(False).astype(bool)
            row["accept_rate"] = float(accepted.mean())
        for a in ANGLES:
            col = f"{a}_err_rad"
            if col in ok and ok[col].notna().any():
                err = ok[col].abs() * ARCSEC_PER_RAD
                row[f"median_abs_{a}_err_arcsec"] = err.median()
                row[f"iqr_abs_{a}_err_arcsec"] = _iqr(err)
                crb = f"crb_{a}_rad"
                if crb in ok and ok[crb].notna().any():
                    row[f"crb_{a}_arcsec"] = float(np.sqrt(np.mean(ok[crb] ** 2))) * ARCSEC_PER_RAD
                    row[f"efficiency_{a}"] = float(np.mean(ok[crb] ** 2) / np.mean(ok[col] ** 2))
        for col in ("scale_err_max", "offset_err_max_nT", "rms_before_nT", "rms_after_nT", "val_rms_after_nT",
                    "rms_reduction_pct", "val_rms_reduction_pct", "heading_err_before_deg", "heading_err_after_deg",
                    "n_evaluations", "n_function_evaluations", "n_jacobians", "runtime_s"):
            if col in ok and ok[col].notna().any():
                row[f"median_{col}"] = float(ok[col].median())
                if col not in ("n_evaluations", "n_function_evaluations", "n_jacobians", "runtime_s", "rms_before_nT",
                               "heading_err_before_deg"):
                    row[f"iqr_{col}"] = _iqr(ok[col])
        if {"efficiency_alpha", "efficiency_beta", "efficiency_gamma"} <= set(row):
            row["efficiency_min_angle"] = min(row[f"efficiency_{a}"] for a in ANGLES)
        out.append(row)
    return pd.DataFrame(out)


MIN_TRIALS_EFFICIENCY = 30
"""Below this many successful trials an efficiency (a ratio of two variances) is too uncertain to quote
without its interval: the tables mark it and the report warns."""
BOOTSTRAP_RESAMPLES = 2000


def efficiency_interval(err: np.ndarray, crb: np.ndarray, level: float = 0.95, resamples: int = BOOTSTRAP_RESAMPLES,
                        seed: int = 0) -> tuple[float, float]:
    """Percentile-bootstrap interval of the efficiency mean(crb²) / mean(err²) over trials (the trials
    resampled with replacement, ``resamples`` times, a fixed seed so that tables are reproducible)."""
    err, crb = np.asarray(err, dtype=float), np.asarray(crb, dtype=float)
    keep = np.isfinite(err) & np.isfinite(crb)
    err, crb = err[keep], crb[keep]
    if len(err) < 2:
        return np.nan, np.nan
    rng = np.random.default_rng(seed)
    idx = rng.integers(0, len(err), size=(resamples, len(err)))
    mse = np.mean(err[idx] ** 2, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        eff = np.mean(crb[idx] ** 2, axis=1) / mse
    eff = eff[np.isfinite(eff)]
    if not len(eff):
        return np.nan, np.nan
    lo, hi = np.quantile(eff, [(1 - level) / 2, (1 + level) / 2])
    return float(lo), float(hi)


def add_intervals(summary: pd.DataFrame, runs: pd.DataFrame) -> pd.DataFrame:
    """``efficiency_<angle>_lo/_hi`` (95 % bootstrap) and ``n_ok`` (the successful runs behind the medians)
    added to a summary of ``runs``."""
    summary = summary.copy()
    for i, row in summary.iterrows():
        part = runs[(runs["scenario"] == row["scenario"]) & (runs["configuration"] == row["configuration"])]
        ok = successful(part)
        summary.loc[i, "n_ok"] = len(ok)
        for a in ANGLES:
            if f"efficiency_{a}" in summary and np.isfinite(row.get(f"efficiency_{a}", np.nan)):
                lo, hi = efficiency_interval(ok[f"{a}_err_rad"].to_numpy(float), ok[f"crb_{a}_rad"].to_numpy(float))
                summary.loc[i, f"efficiency_{a}_lo"], summary.loc[i, f"efficiency_{a}_hi"] = lo, hi
        if np.isfinite(row.get("efficiency_min_angle", np.nan)):
            worst = min(ANGLES, key=lambda a: row[f"efficiency_{a}"])
            summary.loc[i, "efficiency_min_angle_lo"] = summary.loc[i, f"efficiency_{worst}_lo"]
            summary.loc[i, "efficiency_min_angle_hi"] = summary.loc[i, f"efficiency_{worst}_hi"]
    if "n_ok" in summary:
        summary["n_ok"] = summary["n_ok"].astype(int)
    return summary


# ------------------------------------------------------------------------------------ human views
@dataclass(frozen=True)
class Column:
    """A column of the human tables: a median (and its inter-quartile range, when ``iqr``) of ``key``."""

    key: str  # summary column of the value
    title: str  # human name, plain text (Markdown, HTML)
    unit: str = ""  # plain-text unit
    tex_title: str = ""  # LaTeX name (defaults to the escaped title)
    tex_unit: str = ""  # siunitx unit, e.g. \arcsecond
    iqr: str = ""  # summary column of the inter-quartile range
    kind: str = "g"  # g: 3 significant figures; pct: a fraction shown in percent; int; evals


ANGLE_COLUMNS = [Column(f"median_abs_{a}_err_arcsec", f"{g} error", "arcsec", rf"$|\Delta{t}|$", r"\arcsecond",
                        f"iqr_abs_{a}_err_arcsec") for a, g, t in (("alpha", "α", r"\alpha"), ("beta", "β", r"\beta"),
                                                                  ("gamma", "γ", r"\gamma"))]
COLUMNS = {
    "runs": Column("n_runs", "runs", kind="int", tex_title="runs"),
    "success": Column("success_rate", "finished", "%", kind="pct", tex_title=r"finished (\%)"),
    "accepted": Column("accept_rate", "accepted", "%", kind="pct", tex_title=r"accepted (\%)"),
    "scale": Column("median_scale_err_max", "max scale error", "", r"$\max|\Delta k|$", "", "iqr_scale_err_max"),
    "offset": Column("median_offset_err_max_nT", "max offset error", "nT", r"$\max|\Delta o|$", r"\nano\tesla",
                     "iqr_offset_err_max_nT"),
    "rms_fit": Column("median_rms_after_nT", "RMS fit", "nT", "RMS fit", r"\nano\tesla", "iqr_rms_after_nT"),
    "rms_val": Column("median_val_rms_after_nT", "RMS held-out", "nT", "RMS held-out", r"\nano\tesla",
                      "iqr_val_rms_after_nT"),
    "heading": Column("median_heading_err_after_deg", "heading error", "°", "heading error", r"\degree",
                      "iqr_heading_err_after_deg"),
    "efficiency": Column("efficiency_min_angle", "efficiency", "", "efficiency"),
    "evals": Column("median_n_evaluations", "evaluations (equiv.)", kind="evals", tex_title="evaluations"),
    "jacobians": Column("median_n_jacobians", "Jacobians", kind="evals", tex_title="Jacobians"),
    "runtime": Column("median_runtime_s", "runtime", "s", "runtime", r"\second"),
}
MARKDOWN_VIEW = [*ANGLE_COLUMNS, *(COLUMNS[k] for k in ("scale", "offset", "rms_fit", "rms_val", "heading",
                                                          "efficiency", "evals", "jacobians", "runtime"))]
TEX_ANGLES = [COLUMNS["runs"], COLUMNS["success"], *ANGLE_COLUMNS, COLUMNS["efficiency"]]
TEX_PARAMETERS = [*(COLUMNS[k] for k in ("scale", "offset", "heading"))]
TEX_COST = [*(COLUMNS[k] for k in ("rms_fit", "rms_val", "evals", "jacobians", "runtime"))]


def _g(v: float) -> str:
    """3 significant figures; exponent form (``4.5e3``) outside 1e-3 .. 1e5."""
    if not np.isfinite(v):
        return ""
    if v != 0 and not 1e-3 <= abs(v) < 1e5:
        mant, exp = f"{v:.2e}".split("e")
        return f"{mant}e{int(exp)}"
    text = f"{v:.3g}"
    if "e" in text:  # .3g of 1000..99999
        return f"{v:.0f}"
    return text


def _value(r: pd.Series, c: Column, key: str | None = None) -> str:
    v = r.get(key or c.key, np.nan)
    try:
        v = float(v)
    except (TypeError, ValueError):
        return ""
    if not np.isfinite(v):
        return ""
    if c.kind == "pct":
        return f"{100 * v:.0f}"
    if c.kind == "int":
        return f"{int(v)}"
    if c.kind == "evals":
        return evaluations_label(r.get("evaluation_mode", "counted"), v)
    return _g(v)


def _present(summary: pd.DataFrame, cols: list[Column]) -> list[Column]:
    """The columns that have at least one value."""
    import pandas as pd

    return [c for c in cols if c.key in summary and pd.to_numeric(summary[c.key], errors="coerce").notna().any()]


def _few(r: pd.Series) -> bool:
    n = r.get("n_ok", r.get("n_runs", 0))
    return bool(np.isfinite(r.get("efficiency_min_angle", np.nan))) and float(n) < MIN_TRIALS_EFFICIENCY


def efficiency_text(r: pd.Series) -> str:
    """``0.91 (0.62–1.3)`` with the 95 % bootstrap interval, ``†`` when the trials are too few."""
    v = _value(r, COLUMNS["efficiency"])
    if not v:
        return ""
    lo, hi = r.get("efficiency_min_angle_lo", np.nan), r.get("efficiency_min_angle_hi", np.nan)
    if np.isfinite(lo) and np.isfinite(hi):
        v += f" ({_g(lo)}–{_g(hi)})"
    return v + (" †" if _few(r) else "")


def md_escape(text: str) -> str:
    """A table cell for GitHub Markdown: pipes and backslashes escaped, HTML markup neutralized (so a
    label such as ``<script>`` is shown, not run), control characters and line breaks removed."""
    text = "".join(ch if ch.isprintable() else " " for ch in str(text))
    text = text.replace("\\", "\\\\").replace("|", "\\|")
    for a, b in (("&", "&amp;"), ("<", "&lt;"), (">", "&gt;")):
        text = text.replace(a, b)
    for ch in "*_`[]":
        text = text.replace(ch, "\\" + ch)
    return text.strip() or " "


def _md_table(head: list[str], rows: list[list[str]], align: list[str]) -> str:
    sep = {"l": ":---", "r": "---:"}
    lines = ["| " + " | ".join(md_escape(h) for h in head) + " |", "| " + " | ".join(sep[a] for a in align) + " |"]
    lines += ["| " + " | ".join(md_escape(c) if c else "–" for c in r) + " |" for r in rows]
    return "\n".join(lines) + "\n"


def to_markdown(summary: pd.DataFrame) -> str:
    """GitHub Markdown: one row per (scenario, calibrator); a measured quantity as ``median (IQR)``; the
    efficiency with its 95 % bootstrap interval, marked † below ``MIN_TRIALS_EFFICIENCY`` trials."""
    cols = _present(summary, MARKDOWN_VIEW)
    head = ["scenario", "calibrator", "runs", "finished %"] + (["accepted %"] if "accept_rate" in summary else [])
    head += [f"{c.title} ({c.unit})" if c.unit and c.kind != "pct" else c.title for c in cols]
    rows = []
    for _, r in summary.iterrows():
        cells = [str(r["scenario"]), str(r["configuration"]), _value(r, COLUMNS["runs"]), _value(r, COLUMNS["success"])]
        if "accept_rate" in summary:
            cells.append(_value(r, COLUMNS["accepted"]))
        for c in cols:
            if c.key == "efficiency_min_angle":
                cells.append(efficiency_text(r))
                continue
            v = _value(r, c)
            q = _value(r, c, c.iqr) if c.iqr else ""
            cells.append(f"{v} ({q})" if v and q else v)
        rows.append(cells)
    return _md_table(head, rows, ["l", "l"] + ["r"] * (len(head) - 2))


TERMINAL_VIEW = ("runs", "success", "accepted", "rms_fit", "rms_val", "evals", "runtime")


def to_terminal(summary: pd.DataFrame, max_calibrator: int = 28) -> str:
    """A compact plain-text table for the terminal (it must not wrap at 100 columns): scenario, calibrator,
    runs, finished and accepted %, the worst angle error, RMS fit and held-out, evaluations, runtime; the
    full table is summary.md."""
    import pandas as pd

    angle_keys = [c.key for c in ANGLE_COLUMNS if c.key in summary]
    rows = []
    for _, r in summary.iterrows():
        conf = str(r["configuration"])
        conf = conf if len(conf) <= max_calibrator else conf[:max_calibrator - 1] + "…"
        worst = pd.to_numeric(r[angle_keys], errors="coerce").max() if angle_keys else float("nan")
        cells = [str(r["scenario"]), conf]
        for key in TERMINAL_VIEW[:3]:
            if COLUMNS[key].key in summary:
                cells.append(_value(r, COLUMNS[key]))
        cells.append("-" if pd.isna(worst) else f"{worst:.3g}")
        cells += [_value(r, COLUMNS[k]) or "-" for k in TERMINAL_VIEW[3:] if COLUMNS[k].key in summary]
        rows.append(cells)
    head = ["scenario", "calibrator"] + [{"runs": "runs", "success": "fin%", "accepted": "acc%"}[k]
                                         for k in TERMINAL_VIEW[:3] if COLUMNS[k].key in summary]
    head += ["max angle\""] + [{"rms_fit": "RMS nT", "rms_val": "held-out nT", "evals": "evals",
                                "runtime": "runtime s"}[k] for k in TERMINAL_VIEW[3:] if COLUMNS[k].key in summary]
    widths = [max(len(h), *(len(c[i]) for c in rows)) if rows else len(h) for i, h in enumerate(head)]
    def line(cells):
        return "  ".join(c.ljust(w) if i < 2 else c.rjust(w) for i, (c, w) in enumerate(zip(cells, widths)))
    return "\n".join([line(head)] + [line(c) for c in rows]) + "\n"


MARKDOWN_NOTE = ("Finished: runs whose solver ended normally (converged, or stopped by its budget); accepted: runs "
                 "whose answer passed the acceptance checks (a finished run can still be rejected, for example when "
                 "the data do not determine a parameter). Medians over the finished runs, the inter-quartile range "
                 "in parentheses. α, β, γ error: absolute recovery error of the non-orthogonality angles "
                 "(arc-seconds); max scale and max offset error: the largest over the three axes; RMS fit: "
                 "total-field residual on the calibration data; RMS held-out: on a second data set from the same "
                 "sensor. Efficiency: the smallest over the three angles of "
                 "(Cramér-Rao variance) / (mean squared error), 1 for an efficient estimator, with its 95 % bootstrap "
                 f"interval; † marks fewer than {MIN_TRIALS_EFFICIENCY} successful trials, too few for the number "
                 "to mean much.\n")


# ------------------------------------------------------------------------------------------- LaTeX
_TEX_SPECIALS = {"\\": r"\textbackslash{}", "&": r"\&", "%": r"\%", "$": r"\$", "#": r"\#", "_": r"\_",
                 "{": r"\{", "}": r"\}", "~": r"\textasciitilde{}", "^": r"\textasciicircum{}",
                 "<": r"\textless{}", ">": r"\textgreater{}", "|": r"\textbar{}",
                 "α": r"$\alpha$", "β": r"$\beta$", "γ": r"$\gamma$", "″": r"\textquotedbl{}", "°": r"\textdegree{}",
                 "–": "--", "—": "---", "†": r"\textdagger{}"}


def _tex_escape(s: str) -> str:
    """Text for LaTeX: every special character escaped (one pass, so escapes are not escaped again),
    other non-ASCII characters and control characters dropped."""
    return "".join(_TEX_SPECIALS.get(ch, ch if ch.isascii() else "?") for ch in str(s) if ch.isprintable())


def _table_format(cells: list[str]) -> str:
    """siunitx ``table-format`` that holds every number of a column (digits before and after the
    decimal marker, exponent digits)."""
    ints, decs, exps, sign, esign = 1, 0, 0, False, False
    for c in cells:
        if not c or c.startswith("{"):
            continue
        mant, _, exp = c.partition("e")
        sign |= mant.startswith("-")
        whole, _, frac = mant.lstrip("-").partition(".")
        ints, decs = max(ints, len(whole)), max(decs, len(frac))
        if exp:
            esign |= exp.startswith("-")
            exps = max(exps, len(exp.lstrip("-+")))
    fmt = ("-" if sign else "") + f"{ints}.{decs}"
    if exps:
        fmt += "e" + ("-" if esign else "") + str(exps)
    return fmt


def _latex_table(summary: pd.DataFrame, cols: list[Column], caption: str, label: str) -> str:
    import pandas as pd

    header = [("scenario", ""), ("calibrator", "")]
    spans = []  # (first column, last column) of a median + IQR pair, 1-based
    for c in cols:
        title = c.tex_title or _tex_escape(c.title)
        if c.tex_unit:
            title += rf" (\si{{{c.tex_unit}}})"
        if c.key == "efficiency_min_angle":
            header += [(title, "value"), (title, "95\\% low"), (title, "95\\% high")]
            spans.append((len(header) - 2, len(header)))
            continue
        header.append((title, "median" if c.iqr else ""))
        if c.iqr:
            header.append((title, "IQR"))
            spans.append((len(header) - 1, len(header)))
    prev = None
    rows = []
    for _, r in summary.iterrows():
        scen = str(r["scenario"])
        row = [_tex_escape(scen) if scen != prev else "", _tex_escape(r["configuration"])]
        prev = scen
        for c in cols:
            if c.kind == "evals":
                v = _value(r, c)
                row.append(v if v.replace(".", "").isdigit() else "{" + _tex_escape(v) + "}")
            else:
                row.append(_value(r, c))
            if c.iqr:
                row.append(_value(r, c, c.iqr))
            if c.key == "efficiency_min_angle":  # the 95 % bootstrap interval
                row += [_value(r, c, "efficiency_min_angle_lo"), _value(r, c, "efficiency_min_angle_hi")]
        rows.append(row)
    n_cols = len(header)
    formats = []
    for j in range(2, n_cols):
        cells = [row[j] for row in rows]
        formats.append(f"S[table-format={_table_format(cells)}]")
    rows = [[cell if (j < 2 or cell) else "{--}" for j, cell in enumerate(row)] for row in rows]
    frame = pd.DataFrame(rows, columns=pd.MultiIndex.from_tuples(header))
    tex = frame.style.hide(axis="index").to_latex(
        column_format="ll" + "".join(formats), hrules=True, siunitx=True, caption=caption, label=label,
        position="htbp", position_float="centering", multicol_align="c")
    lines = tex.splitlines()
    # booktabs: a partial rule under each median/IQR pair, a thin rule between scenarios, small type
    head_end = next(i for i, line in enumerate(lines) if line.startswith("\\toprule")) + 1
    lines.insert(head_end + 1, "".join(rf"\cmidrule(lr){{{a}-{b}}}" for a, b in spans))
    # small type; scaled down (never up) to the line width if still too wide (adjustbox)
    lines.insert(next(i for i, line in enumerate(lines) if line.startswith("\\begin{tabular")),
                 r"\small\setlength{\tabcolsep}{3pt}\begin{adjustbox}{max width=\linewidth}")
    lines.insert(next(i for i, line in enumerate(lines) if line.startswith("\\end{tabular")) + 1,
                 r"\end{adjustbox}")
    body = next(i for i, line in enumerate(lines) if line.startswith("\\midrule")) + 1
    end = next(i for i, line in enumerate(lines) if line.startswith("\\bottomrule"))
    out = lines[:body]
    for i in range(body, end):
        if i > body and not lines[i].startswith(" &"):  # a new scenario
            out.append(r"\addlinespace")
        out.append(lines[i])
    out += lines[end:]
    return "\n".join(out) + "\n"


def warm_latex() -> None:
    """Import pandas' Styler and compile its LaTeX templates (jinja2, cached for the process) on a table of one cell
    with ``_latex_table``'s options: a campaign on local workers does this while its workers run, so that its first
    real table does not (0.2-0.3 s of a campaign's serial tail)."""
    import pandas as pd

    frame = pd.DataFrame([["a", "1"]], columns=pd.MultiIndex.from_tuples([("x", ""), ("y", "median")]))
    frame.style.hide(axis="index").to_latex(column_format="lS", hrules=True, siunitx=True, caption="c", label="l",
                                            position="htbp", position_float="centering", multicol_align="c")


TEX_PREAMBLE = ("% magbench campaign tables (written by magbench compare). Needs in the preamble:\n"
                "% \\usepackage{booktabs} \\usepackage{siunitx} (version 3) \\usepackage{adjustbox} "
                "\\usepackage{textcomp}\n")


def to_latex(summary: pd.DataFrame) -> str:
    """Two page-wide booktabs tables with siunitx-aligned numbers (pandas' ``Styler.to_latex``): the angle
    recovery (medians and inter-quartile ranges, efficiency) and the residuals and cost."""
    parts = [TEX_PREAMBLE]
    angles = _present(summary, TEX_ANGLES)
    few = [r for _, r in summary.iterrows() if _few(r)]
    note = ""
    if few and len(few) == len(summary):
        note = (f" Every efficiency here rests on fewer than {MIN_TRIALS_EFFICIENCY} successful trials: too few "
                "for the number to mean much; see the width of its interval.")
    elif few:
        note = (f" Fewer than {MIN_TRIALS_EFFICIENCY} successful trials, too few for the efficiency to mean much: "
                + "; ".join(_tex_escape(f"{r['scenario']} {r['configuration']}") for r in few) + ".")
    if any(c.iqr for c in angles):
        parts.append(_latex_table(
            summary, angles, "Recovery of the non-orthogonality angles: median and inter-quartile range (IQR) over "
            "the successful runs of the absolute error; efficiency is the smallest over the three angles of the "
            "Cram\\'er--Rao variance over the mean squared error (1: efficient), with its 95\\% bootstrap interval."
            + note, "tab:magbench-angles"))
    params = _present(summary, TEX_PARAMETERS)
    if params:
        parts.append(_latex_table(
            summary, params, "Recovery of the scale factors and offsets (largest error over the three axes) and "
            "the heading error after calibration: median and inter-quartile range (IQR) over the successful runs.",
            "tab:magbench-parameters"))
    cost = _present(summary, TEX_COST)
    if cost:
        parts.append(_latex_table(
            summary, cost, "Residuals and cost: total-field RMS residual on the calibration data (fit) and on a "
            "second data set of the same sensor (held-out), median and inter-quartile range (IQR) over the "
            "successful runs; median objective evaluations and runtime per calibration.", "tab:magbench-cost"))
    return "\n".join(parts)


def write_output(path: Path, text: str) -> Path:
    """A campaign's output file written whole or not at all (``safeio.atomic_write``: a temporary file renamed onto
    ``path``), so that a symbolic link already standing at ``path`` is replaced, never written through (a link named
    report.html or summary.md had sent a rewritten table or report into the campaign's runs.csv, or outside it)."""
    return atomic_write(path, text, force=True)


_WRITTEN_SUMMARY: dict[str, pd.DataFrame] = {}
"""sha256 of the runs.csv this process last wrote -> the summary computed from those runs (``written_summary``)."""


def written_summary(runs_csv: Path) -> pd.DataFrame | None:
    """The summary ``write_tables`` computed when this process wrote ``runs_csv`` as it now is (its bytes' sha256),
    else None: a campaign's report need not compute it again."""
    if not _WRITTEN_SUMMARY:
        return None
    try:
        key = hashlib.sha256(Path(runs_csv).read_bytes()).hexdigest()
    except OSError:
        return None
    return _WRITTEN_SUMMARY.get(key)


def write_tables(runs: pd.DataFrame, traces: pd.DataFrame, fields: pd.DataFrame, manifest: dict, out: Path) -> None:
    out = Path(out)
    runs_text = runs.to_csv(index=False, float_format=FLOAT_FORMAT, lineterminator="\n")
    write_output(out / "runs.csv", runs_text)
    summary = add_intervals(summarize(runs), runs) if len(runs) else summarize(runs)
    _WRITTEN_SUMMARY.clear()
    _WRITTEN_SUMMARY[hashlib.sha256(runs_text.encode("utf-8")).hexdigest()] = summary
    write_output(out / "summary.csv", summary.to_csv(index=False, float_format=FLOAT_FORMAT, lineterminator="\n"))
    write_output(out / "summary.md", to_markdown(summary) + "\n" + MARKDOWN_NOTE)
    write_output(out / "summary.tex", to_latex(summary))
    if len(traces):
        write_output(out / "traces.csv", traces.to_csv(index=False, float_format=FLOAT_FORMAT, lineterminator="\n"))
    if len(fields):
        write_output(out / "fields.csv", fields.to_csv(index=False, float_format=FLOAT_FORMAT, lineterminator="\n"))
    write_output(out / "manifest.json", json.dumps(manifest, indent=2, default=str) + "\n")

"""Campaign tables: the runs as a tidy CSV, summaries (median, inter-quartile range, success rate,
efficiency against the Cramér-Rao bound) in CSV, Markdown and LaTeX, and the manifest."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd

from magbench.benchmarks.metrics import evaluations_label
from magbench.paper import ARCSEC_PER_RAD

ANGLES = ("alpha", "beta", "gamma")
FLOAT_FORMAT = "%.10g"


def _iqr(v: pd.Series) -> float:
    v = v.dropna()
    return float(v.quantile(0.75) - v.quantile(0.25)) if len(v) else np.nan


def summarize(runs: pd.DataFrame) -> pd.DataFrame:
    """One row per (scenario, configuration), in the order they appear in ``runs``."""
    out = []
    for (scenario, conf), part in runs.groupby(["scenario", "configuration"], sort=False):
        ok = part[(part["error"] == "") & part.get("success", pd.Series(True, index=part.index)).fillna(False).astype(bool)]
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
                    "n_evaluations", "runtime_s"):
            if col in ok and ok[col].notna().any():
                row[f"median_{col}"] = float(ok[col].median())
                if col not in ("n_evaluations", "runtime_s", "rms_before_nT", "heading_err_before_deg"):
                    row[f"iqr_{col}"] = _iqr(ok[col])
        if {"efficiency_alpha", "efficiency_beta", "efficiency_gamma"} <= set(row):
            row["efficiency_min_angle"] = min(row[f"efficiency_{a}"] for a in ANGLES)
        out.append(row)
    return pd.DataFrame(out)


# compact view for the human tables: (column, header, format)
VIEW = [("scenario", "scenario", "{}"), ("configuration", "calibrator", "{}"), ("n_runs", "runs", "{:d}"),
        ("success_rate", "success", "{:.0%}"), ("accept_rate", "accepted", "{:.0%}"),
        ("median_abs_alpha_err_arcsec", "|dα| ″", "{:.3g}"), ("median_abs_beta_err_arcsec", "|dβ| ″", "{:.3g}"),
        ("median_abs_gamma_err_arcsec", "|dγ| ″", "{:.3g}"), ("median_scale_err_max", "|dk| max", "{:.2g}"),
        ("median_offset_err_max_nT", "|do| max nT", "{:.3g}"), ("median_rms_after_nT", "RMS fit nT", "{:.3g}"),
        ("median_val_rms_after_nT", "RMS held-out nT", "{:.3g}"),
        ("median_val_rms_reduction_pct", "reduction %", "{:.1f}"),
        ("median_heading_err_after_deg", "heading °", "{:.3g}"), ("efficiency_min_angle", "efficiency", "{:.2f}"),
        ("median_n_evaluations", "evals", "{:.0f}"), ("median_runtime_s", "runtime s", "{:.3g}")]


def _cells(summary: pd.DataFrame) -> tuple[list[str], list[list[str]]]:
    cols = [(c, h, f) for c, h, f in VIEW if c in summary]
    rows = []
    for _, r in summary.iterrows():
        cells = []
        for c, _, f in cols:
            v = r[c]
            if c == "median_n_evaluations":
                cells.append(evaluations_label(r.get("evaluation_mode", "counted"), float(v)))
            elif isinstance(v, float) and np.isnan(v):
                cells.append("-")
            else:
                cells.append(f.format(int(v) if f == "{:d}" else v))
        rows.append(cells)
    return [h for _, h, _ in cols], rows


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


def to_markdown(summary: pd.DataFrame) -> str:
    head, rows = _cells(summary)
    lines = ["| " + " | ".join(md_escape(h) for h in head) + " |", "|" + "---|" * len(head)]
    lines += ["| " + " | ".join(md_escape(c) for c in r) + " |" for r in rows]
    return "\n".join(lines) + "\n"


_TEX_SPECIALS = {"\\": r"\textbackslash{}", "&": r"\&", "%": r"\%", "$": r"\$", "#": r"\#", "_": r"\_",
                 "{": r"\{", "}": r"\}", "~": r"\textasciitilde{}", "^": r"\textasciicircum{}",
                 "<": r"\textless{}", ">": r"\textgreater{}", "|": r"\textbar{}",
                 "α": r"$\alpha$", "β": r"$\beta$", "γ": r"$\gamma$", "″": r"$''$", "°": r"$^\circ$"}


def _tex_escape(s: str) -> str:
    """Text for LaTeX: every special character escaped (one pass, so escapes are not escaped again),
    control characters dropped."""
    return "".join(_TEX_SPECIALS.get(ch, ch) for ch in str(s) if ch.isprintable())


def to_latex(summary: pd.DataFrame) -> str:
    head, rows = _cells(summary)
    lines = [r"\begin{tabular}{ll" + "r" * (len(head) - 2) + "}", r"\hline",
             " & ".join(_tex_escape(h) for h in head) + r" \\", r"\hline"]
    lines += [" & ".join(_tex_escape(c) for c in r) + r" \\" for r in rows]
    lines += [r"\hline", r"\end{tabular}"]
    return "\n".join(lines) + "\n"


def write_tables(runs: pd.DataFrame, traces: pd.DataFrame, fields: pd.DataFrame, manifest: dict, out: Path) -> None:
    out = Path(out)
    runs.to_csv(out / "runs.csv", index=False, float_format=FLOAT_FORMAT, lineterminator="\n")
    summary = summarize(runs)
    summary.to_csv(out / "summary.csv", index=False, float_format=FLOAT_FORMAT, lineterminator="\n")
    note = ("Medians over successful runs; |dα| etc. are absolute recovery errors in arc-seconds; efficiency is the "
            "smallest over the three angles of (Cramér-Rao variance) / (mean squared error); RMS held-out is on a "
            "second data set from the same sensor.\n")
    (out / "summary.md").write_text(to_markdown(summary) + "\n" + note, encoding="utf-8")
    (out / "summary.tex").write_text(to_latex(summary), encoding="utf-8")
    if len(traces):
        traces.to_csv(out / "traces.csv", index=False, float_format=FLOAT_FORMAT, lineterminator="\n")
    if len(fields):
        fields.to_csv(out / "fields.csv", index=False, float_format=FLOAT_FORMAT, lineterminator="\n")
    (out / "manifest.json").write_text(json.dumps(manifest, indent=2, default=str) + "\n", encoding="utf-8")

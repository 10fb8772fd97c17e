"""One self-contained HTML page for a campaign directory: manifest, summary table, every figure (PNG
embedded as base64), failed runs and the command that made the campaign.

    from magbench.benchmarks.report import write_report
    write_report("results/campaign")          # -> results/campaign/report.html

No external resources, no timestamps of its own: the same directory gives the same bytes.
"""
from __future__ import annotations

import base64
import html
import json
import shlex
from pathlib import Path

import numpy as np
import pandas as pd

from magbench.benchmarks.figures import KINDS, failed_mask, make_figures

CAPTIONS = {
    "errors": "Angle recovery errors (estimate − truth, arcsec) per configuration; boxes span the inter-quartile "
              "range, points are single runs, the shaded band is the Cramér-Rao ±1σ (median over trials). "
              "Failed runs are excluded.",
    "accuracy_runtime": "Median RMS angle error √((α²+β²+γ²)/3) against median runtime per configuration; "
                        "bars are inter-quartile ranges.",
    "convergence": "Convergence: best F (solid) and batch mean F (dashed) against cumulative objective "
                   "evaluations; F is the mean squared total-field error (nT², eq. 3).",
    "field_heading": "Total field against turntable heading: raw readings, reference and each configuration's "
                     "corrected field (top); corrected field minus the reference (bottom).",
    "efficiency": "Efficiency against the Cramér-Rao bound (CRB variance / mean squared error) of α, β, γ; "
                  "1 is efficient.",
}

CSS = """
body{font-family:system-ui,-apple-system,"Segoe UI",Helvetica,Arial,sans-serif;margin:2em auto;max-width:1200px;
padding:0 1em;color:#222;line-height:1.4}
h1{font-size:1.6em;border-bottom:2px solid #444;padding-bottom:.2em}
h2{font-size:1.25em;margin-top:1.8em;border-bottom:1px solid #bbb}
h3{font-size:1.05em;margin-top:1.4em}
table{border-collapse:collapse;font-size:.85em;margin:.6em 0}
th,td{border:1px solid #ccc;padding:.25em .5em;text-align:left;vertical-align:top}
th{background:#f0f0f0}
td.num,table.summary td{text-align:right;font-variant-numeric:tabular-nums}
table.summary td:first-child,table.summary td:nth-child(2){text-align:left}
.scroll{overflow-x:auto}
figure{margin:1em 0 2em 0}
figure img{max-width:100%;height:auto;border:1px solid #ddd}
figcaption{font-size:.85em;color:#444;margin-top:.3em}
code,pre{font-family:ui-monospace,Menlo,Consolas,monospace;font-size:.9em}
pre{background:#f6f6f6;padding:.5em;overflow-x:auto;white-space:pre-wrap}
footer{margin-top:3em;border-top:1px solid #bbb;padding-top:.5em;font-size:.85em;color:#555}
""".strip()


def _esc(value: object) -> str:
    return html.escape(str(value), quote=True)


def _read_manifest(path: Path) -> dict:
    """The manifest as a dict; empty if missing or not a JSON object."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


def _flatten(obj: object, prefix: str = "") -> list[tuple[str, str]]:
    """(dotted key, text) pairs of a nested manifest; lists of scalars joined, other lists as JSON."""
    if isinstance(obj, dict):
        rows: list[tuple[str, str]] = []
        for k, v in obj.items():
            rows += _flatten(v, f"{prefix}.{k}" if prefix else str(k))
        return rows or [(prefix, "{}")]
    if isinstance(obj, list) and all(not isinstance(v, (dict, list)) for v in obj):
        return [(prefix, ", ".join(str(v) for v in obj))]
    if isinstance(obj, (list, tuple)):
        return [(prefix, json.dumps(obj, sort_keys=True, ensure_ascii=False))]
    return [(prefix, "" if obj is None else str(obj))]


def _manifest_html(manifest: dict) -> str:
    if not manifest:
        return "<p>No manifest.json.</p>"
    first = ("root_seed", "seed", "git_commit", "commit", "git", "versions", "machine")
    keys = [k for k in first if k in manifest] + [k for k in manifest if k not in first and k != "command"]
    rows = []
    for k in keys:
        for key, text in _flatten(manifest[k], str(k)):
            rows.append(f"<tr><th>{_esc(key)}</th><td><code>{_esc(text)}</code></td></tr>")
    return "<table class=\"manifest\">\n" + "\n".join(rows) + "\n</table>"


def _fmt(v: object) -> str:
    if isinstance(v, (float, np.floating)):
        return "–" if not np.isfinite(v) else f"{v:.4g}"
    return str(v)


def _summary_html(campaign_dir: Path) -> str:
    path = campaign_dir / "summary.csv"
    try:
        summary = pd.read_csv(path)
    except (OSError, pd.errors.EmptyDataError, pd.errors.ParserError):
        md = campaign_dir / "summary.md"
        if md.is_file():
            return f"<pre>{_esc(md.read_text(encoding='utf-8'))}</pre>"
        return "<p>No summary.csv.</p>"
    table = summary.to_html(index=False, escape=True, na_rep="–", border=0, classes="summary",
                            float_format=lambda v: _fmt(float(v)), justify="left")
    return f"<div class=\"scroll\">\n{table}\n</div>"


def _failures_html(campaign_dir: Path) -> str:
    path = campaign_dir / "runs.csv"
    try:
        runs = pd.read_csv(path, dtype={"error": str, "configuration": str, "scenario": str})
    except (OSError, pd.errors.EmptyDataError, pd.errors.ParserError):
        return "<p>No runs.csv.</p>"
    failed = runs[failed_mask(runs)]
    head = f"<p>{len(failed)} of {len(runs)} runs failed.</p>"
    if failed.empty:
        return head
    errors = failed["error"].astype(str).str.strip()
    rows = []
    for text in pd.unique(errors):
        sel = failed[errors == text]
        where = sorted({f"{s} / {c}" for s, c in zip(sel.get("scenario", pd.Series("", index=sel.index)).fillna(""),
                                                      sel.get("configuration", pd.Series("", index=sel.index))
                                                      .fillna(""))})
        rows.append(f"<tr><td class=\"num\">{len(sel)}</td><td><code>{_esc(text)}</code></td>"
                    f"<td>{'<br>'.join(_esc(w) for w in where)}</td></tr>")
    return (head + "\n<table class=\"failures\">\n<tr><th>runs</th><th>error</th><th>scenario / configuration"
            "</th></tr>\n" + "\n".join(rows) + "\n</table>")


def _split_stem(stem: str) -> tuple[str, str]:
    """(kind, scenario) of a figure file stem ``<kind>_<scenario>``."""
    for kind in sorted(KINDS, key=len, reverse=True):
        if stem.startswith(kind + "_"):
            return kind, stem[len(kind) + 1:]
    return "", stem


def _figures_html(fig_dir: Path) -> str:
    pngs = sorted(fig_dir.glob("*.png")) if fig_dir.is_dir() else []
    if not pngs:
        return "<p>No figures.</p>"
    order = {k: i for i, k in enumerate(KINDS)}
    items = sorted(((*_split_stem(p.stem), p) for p in pngs),
                   key=lambda t: (t[1], order.get(t[0], len(KINDS)), t[2].name))
    parts, current = [], None
    for kind, scenario, png in items:
        if scenario != current:
            parts.append(f"<h3>Scenario <code>{_esc(scenario)}</code></h3>")
            current = scenario
        data = base64.b64encode(png.read_bytes()).decode("ascii")
        caption = CAPTIONS.get(kind, "Figure.")
        parts.append(f"<figure>\n<img src=\"data:image/png;base64,{data}\" alt=\"{_esc(png.stem)}\">\n"
                     f"<figcaption><b>{_esc(png.name)}</b> — {_esc(caption)}</figcaption>\n</figure>")
    return "\n".join(parts)


def _command_text(manifest: dict) -> str:
    cmd = manifest.get("command")
    if isinstance(cmd, (list, tuple)):
        return shlex.join(str(c) for c in cmd)
    return str(cmd) if cmd else ""


def write_report(campaign_dir: str | Path, out: str | Path | None = None) -> Path:
    """Write the campaign's single-file HTML report and return its path."""
    campaign_dir = Path(campaign_dir)
    out = Path(out) if out is not None else campaign_dir / "report.html"
    fig_dir = campaign_dir / "figures"
    if not fig_dir.is_dir() or not any(fig_dir.glob("*.png")):
        make_figures(campaign_dir, fig_dir)
    manifest = _read_manifest(campaign_dir / "manifest.json")
    command = _command_text(manifest)
    footer = (f"Campaign made by <code>{_esc(command)}</code>; report written by "
              f"<code>benchmarks.report.write_report</code>." if command else
              "Report written by <code>benchmarks.report.write_report</code>; the manifest does not record the "
              "campaign's command.")
    title = f"magbench campaign report — {campaign_dir.resolve().name}"
    page = [
        "<!DOCTYPE html>",
        "<html lang=\"en\">",
        "<head>",
        "<meta charset=\"utf-8\">",
        f"<title>{_esc(title)}</title>",
        f"<style>\n{CSS}\n</style>",
        "</head>",
        "<body>",
        f"<h1>{_esc(title)}</h1>",
        "<h2>Manifest</h2>",
        _manifest_html(manifest),
        "<h2>Summary</h2>",
        _summary_html(campaign_dir),
        "<h2>Failed runs</h2>",
        _failures_html(campaign_dir),
        "<h2>Figures</h2>",
        _figures_html(fig_dir),
        f"<footer>{footer}</footer>",
        "</body>",
        "</html>",
        "",
    ]
    out.parent.mkdir(parents=True, exist_ok=True)
    with open(out, "w", encoding="utf-8", newline="\n") as fh:
        fh.write("\n".join(page))
    return out

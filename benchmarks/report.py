"""One self-contained HTML page for a campaign directory: results first (one table per scenario, human
column names, medians with their inter-quartile ranges), a contents list, every figure (PNG embedded as
base64) with a warning wherever the trials are too few for what it shows, the failed runs, and the
campaign's details (command, manifest) last.

    from magbench.benchmarks.report import write_report
    write_report("results/campaign")          # -> results/campaign/report.html

The page is a Jinja2 template (``templates/report.html.j2``, autoescaped); no external resources, no
timestamps of its own: the same directory gives the same bytes.
"""
from __future__ import annotations

import base64
import glob
import json
import re
import shlex
from pathlib import Path
from urllib.parse import quote

import pandas as pd

from magbench.benchmarks.comparison import ert_cell
from magbench.benchmarks.comparison_figures import COMPARISON_KINDS
from magbench.benchmarks.figures import KINDS, failed_mask, make_figures, safe_name
from magbench.benchmarks.styles import campaign_styles, swatch_svg
from magbench.benchmarks.tables import (
    ANGLE_COLUMNS,
    COLUMNS,
    MIN_TRIALS_EFFICIENCY,
    _few,
    _value,
    add_intervals,
    efficiency_text,
    summarize,
    write_output,
    written_summary,
)
from magbench.errors import InputError
from magbench.safeio import os_reason
from magbench.simulate.scenarios import get_scenario

TEMPLATES = Path(__file__).with_name("templates")

TITLES = {"errors": "Angle errors relative to the Cramér-Rao bound",
          "accuracy_runtime": "Accuracy against runtime",
          "convergence": "Convergence over all trials",
          "field_heading": "Total field against heading",
          "efficiency": "Efficiency against the Cramér-Rao bound"}
CAPTIONS = {
    "errors": "|estimate − truth| of each angle divided by the run's Cramér-Rao standard deviation, on one "
              "logarithmic axis for the three panels; boxes span the inter-quartile range, points are single runs, "
              "the grey region lies within one standard deviation of the bound (the dashed line). Failed runs are "
              "excluded.",
    "accuracy_runtime": "Median over runs of the RMS over α, β, γ of the error relative to the Cramér-Rao "
                        "standard deviation, against the median runtime per calibration; bars are inter-quartile "
                        "ranges; the grey line is the bound.",
    "convergence": "RMS total-field residual of the best point found so far (√F, F the mean squared total-field "
                   "error of eq. 3) against objective evaluations: the median over all trials and the "
                   "inter-quartile band. Methods that finish in a few evaluations are drawn as a marker with its "
                   "inter-quartile bar.",
    "field_heading": "Trial 0: total field of the raw readings, the reference and each calibrator's corrected field "
                     "against heading (top); corrected field minus the reference (bottom). Drawn only for scenarios "
                     "with a heading (a turntable, a vehicle turning).",
    "efficiency": "Cramér-Rao variance over the mean squared error of α, β, γ per calibrator (1: efficient) with "
                  "95 % percentile-bootstrap intervals over the trials; logarithmic axis.",
}
EXTRA = {"ecdf": ("Runtime ECDFs", "Fraction of (run, target) pairs reached against evaluations."),
         "anytime": ("Anytime curves", "Median and inter-quartile band over trials of the best RMS so far relative "
                                       "to the trial's optimum."),
         "profile": ("Performance profiles", "Dolan-Moré profiles across scenarios of the expected running time "
                                             "to the 1.01 × optimum target.")}
FEW_TRIALS_CURVES = 5

CSS = """
:root{--warn-bg:#fff6dc;--warn-border:#d8a400;--muted:#555}
*{box-sizing:border-box}
body{font-family:system-ui,-apple-system,"Segoe UI",Helvetica,Arial,sans-serif;margin:1.5em auto;max-width:1280px;
padding:0 1em;color:#222;line-height:1.4;overflow-wrap:break-word}
h1{font-size:1.6em;border-bottom:2px solid #444;padding-bottom:.2em;margin-bottom:.3em}
h2{font-size:1.3em;margin-top:1.8em;border-bottom:1px solid #bbb}
h3{font-size:1.1em;margin-top:1.4em}
.lede{color:var(--muted);margin-top:0}
.warnings,.warn{background:var(--warn-bg);border-left:4px solid var(--warn-border);padding:.4em .8em}
.warnings ul{margin:.3em 0;padding-left:1.2em}
.warn{margin:.4em 0;font-size:.9em}
nav.toc{background:#f6f6f6;padding:.3em 1em .6em;margin:1em 0}
nav.toc h2{margin-top:.3em;border:0;font-size:1.1em}
nav.toc ol{margin:.2em 0}
nav.toc ol ol{display:flex;flex-wrap:wrap;gap:.2em 1.4em;padding-left:1.2em;list-style:none}
table{border-collapse:collapse;font-size:.82em;margin:.6em 0}
th,td{border:1px solid #ccc;padding:.2em .4em;vertical-align:top}
th{background:#f0f0f0;text-align:center;font-weight:600}
table.summary{width:100%;border-collapse:separate;border-spacing:0;border:solid #ccc;border-width:1px 0 0 1px}
table.summary th,table.summary td{border-width:0 1px 1px 0}
table.summary td{text-align:right;font-variant-numeric:tabular-nums;white-space:nowrap}
table.summary td.text{text-align:left}
td.fewtrials{background:var(--warn-bg)}
.swatch{display:inline-block;width:2.2em;height:1em;margin-right:.3em;vertical-align:-.15em;flex:none}
.scroll{overflow-x:auto;max-width:100%;margin:.6em 0}
.scroll>table{margin:0}
.scroll:focus-visible{outline:2px solid #3867b0;outline-offset:2px}
table.summary th:first-child,table.summary td:first-child{position:sticky;left:0;z-index:1}
table.summary td:first-child{background:#fff}
details.defs{margin:.4em 0 1em;font-size:.9em}
details.defs summary{cursor:pointer;font-weight:600}
details.defs dl{margin:.4em 0;display:grid;grid-template-columns:minmax(7em,max-content) 1fr;gap:.25em 1em}
details.defs dt{font-weight:600}
details.defs dd{margin:0}
.unit,.iqr{color:var(--muted);font-weight:normal;font-size:.88em}
.note,.desc{color:var(--muted);font-size:.9em}
figure{margin:1em 0 2em 0}
figure img{max-width:100%;height:auto;border:1px solid #ddd;display:block}
figure a.full{display:inline-block;max-width:100%}
figcaption{font-size:.88em;color:#333;margin-top:.3em;max-width:70em}
.files{color:var(--muted)}
table.manifest th{text-align:left;white-space:nowrap}
table.manifest td,table.failures td{overflow-wrap:anywhere}
table.failures td.num{text-align:right}
code,pre{font-family:ui-monospace,Menlo,Consolas,monospace;font-size:.9em}
pre{background:#f6f6f6;padding:.5em;white-space:pre-wrap;overflow-wrap:anywhere}
footer{margin-top:3em;border-top:1px solid #bbb;padding-top:.5em;font-size:.85em;color:var(--muted)}
@media (max-width:600px){
body{padding:0 .6em;margin:1em auto}
details.defs dl{display:block}
table.summary th{min-width:6.5em}
details.defs dd{margin:0 0 .4em 1em}
table.manifest,table.manifest tbody,table.manifest tr,table.manifest th,table.manifest td{display:block}
table.manifest tr{border:1px solid #ccc;margin-top:-1px}
table.manifest th,table.manifest td{border:0}
table.manifest th{white-space:normal;overflow-wrap:anywhere}
}
""".strip()


# ---------------------------------------------------------------------------------------------- data


def read_manifest(path: Path) -> dict | None:
    """The campaign's manifest.json as a dict, None when there is none.  One that is there but damaged (cut
    short, not UTF-8, not JSON, or JSON that is not an object) is an ``InputError`` naming it: the report takes
    the campaign's completeness, root seed, trials and skipped runs from it, and had read such a file as empty,
    printing 'root seed ?' and no word of a campaign that was incomplete."""
    path = Path(path)
    if not path.exists() and not path.is_symlink():
        return None
    try:
        data = json.loads(path.read_bytes().decode("utf-8"))
    except OSError as exc:
        raise InputError(f"cannot read {path}: {os_reason(exc)}") from None
    except UnicodeDecodeError:
        why = "not UTF-8 text"
    except json.JSONDecodeError as exc:
        why = "empty" if not exc.doc.strip() else f"not JSON: {exc.msg}, line {exc.lineno}"
    except (ValueError, RecursionError) as exc:
        why = f"not JSON ({type(exc).__name__})"
    else:
        if isinstance(data, dict):
            return data
        why = f"JSON {type(data).__name__}, not an object"
    checkpoint = path.parent / "runs.partial.jsonl"
    mend = (f"its compare command run again with --resume rewrites it from {checkpoint.name}" if checkpoint.is_file()
            else "restore it, or run the campaign again")
    raise InputError(f"{path} is damaged ({why}): the report takes the campaign's completeness, root seed and "
                     f"skipped runs from it; {mend}")


MANIFEST_UNKNOWNS = "whether the campaign is complete, its root seed and its skipped runs are not known"
"""What a campaign folder without a manifest leaves unsaid: the report's warning and ``magbench report``'s line."""


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


def _manifest_rows(manifest: dict) -> list[tuple[str, str]]:
    first = ("root_seed", "seed", "trials", "complete", "git_commit", "versions", "python", "machine")
    keys = [k for k in first if k in manifest] + [k for k in manifest if k not in first and k != "command"]
    return [row for k in keys for row in _flatten(manifest[k], str(k))]


def _read_runs(campaign_dir: Path) -> pd.DataFrame:
    try:
        runs = pd.read_csv(campaign_dir / "runs.csv", dtype={"error": str, "configuration": str, "scenario": str})
    except (OSError, pd.errors.EmptyDataError, pd.errors.ParserError):
        return pd.DataFrame()
    if "error" in runs:
        runs["error"] = runs["error"].fillna("")
    return runs


def _summary(campaign_dir: Path, runs: pd.DataFrame) -> pd.DataFrame:
    """The summary of runs.csv, computed from it as the campaign computed summary.csv (``write_tables``): the report
    states what the runs hold, and summary.csv is not taken on trust (an edited n_runs of 77 had been printed beside
    '4 runs', a garbage summary.csv had given an empty table, both with exit 0; a runs.csv cut to its header had shown
    '0 runs' above summary.csv's table of runs).  Where this process wrote that very runs.csv (a campaign's report),
    the summary it computed then (``tables.written_summary``), not a second one (2.5 s for 2850 runs)."""
    if not len(runs):
        return pd.DataFrame()
    written = written_summary(campaign_dir / "runs.csv")
    return written if written is not None else add_intervals(summarize(runs), runs)


def _scenario_description(name: str) -> str:
    try:
        return get_scenario(name).description
    except Exception:  # a scenario this installation does not know
        return ""


# -------------------------------------------------------------------------------------------- tables

HEADERS = [("calibrator", "", "the calibration method and its hyperparameters"), ("runs", "", "runs in the campaign"),
           ("finished", "%", "runs whose solver ended normally (converged, or stopped by its budget); the answer may "
            "still be rejected"), ("accepted", "%", "runs whose answer passed the acceptance checks: a number magbench "
                                   "stands behind")]


def _columns(summary: pd.DataFrame) -> list:
    """The measured columns that have a value somewhere in the campaign."""
    keys = [*ANGLE_COLUMNS, *(COLUMNS[k] for k in ("scale", "offset", "rms_fit", "rms_val", "heading", "efficiency",
                                                    "evals", "runtime"))]
    return [c for c in keys if c.key in summary and pd.to_numeric(summary[c.key], errors="coerce").notna().any()]


def _header(summary: pd.DataFrame, cols: list) -> list[dict]:
    tips = {**{f"median_abs_{a}_err_arcsec": f"absolute error of the recovered non-orthogonality angle {g}"
               for a, g in (("alpha", "α"), ("beta", "β"), ("gamma", "γ"))},
            "median_scale_err_max": "largest scale-factor error over the axes",
            "median_offset_err_max_nT": "largest offset error over the axes",
            "median_rms_after_nT": "total-field RMS residual on the calibration data",
            "median_val_rms_after_nT": "total-field RMS residual on a second data set of the same sensor",
            "median_heading_err_after_deg": "RMS compass-heading error of the corrected field, levelled with the "
                                            "true attitude",
            "median_n_evaluations": "objective evaluations in evaluation-equivalents (the budget's unit: one per "
                                    "objective value or residual vector, p per Jacobian of p free parameters)",
            "median_runtime_s": "wall-clock time of one calibration",
            "efficiency_min_angle": "smallest over α, β, γ of Cramér-Rao variance / mean squared error (1: "
                                    "efficient), with its 95 % bootstrap interval"}
    head = [{"name": n, "unit": u, "tip": t} for n, u, t in HEADERS if n != "accepted" or "accept_rate" in summary]
    for c in cols:
        unit = c.unit if c.key != "efficiency_min_angle" else "95 % interval"
        if c.iqr:
            unit = f"{unit}, median (IQR)" if unit else "median (IQR)"
        head.append({"name": c.title, "unit": unit, "tip": tips.get(c.key, "")})
    return head


def _rows(part: pd.DataFrame, cols: list, accept: bool, styles: dict | None = None) -> list[list[dict]]:
    """The results table's cells; the calibrator's cell starts with its style in every figure (colour, marker
    and line style, as a small inline SVG: ``styles.swatch_svg``), so that two configurations sharing a colour
    are told apart here as in the figures."""
    from markupsafe import Markup, escape

    styles = styles or {}
    rows = []
    for _, r in part.iterrows():
        name = str(r["configuration"])
        style = styles.get(name)
        label = Markup(swatch_svg(style, f"{name}'s style in the figures")) + escape(name) if style else name
        cells = [{"value": label, "cls": "text"},
                 {"value": _value(r, COLUMNS["runs"]), "cls": ""},
                 {"value": _value(r, COLUMNS["success"]), "cls": ""}]
        if accept:
            cells.append({"value": _value(r, COLUMNS["accepted"]) or "–", "cls": ""})
        for c in cols:
            if c.key == "efficiency_min_angle":
                text = efficiency_text(r).replace(" †", "")
                value, _, interval = text.partition(" ")
                few = _few(r)
                cells.append({"value": (("⚠ " if few else "") + value) if value else "–",
                              "sub": interval.strip("()"), "cls": "fewtrials" if few else "",
                              "tip": f"from {int(r.get('n_ok', r['n_runs']))} trials: fewer than "
                                     f"{MIN_TRIALS_EFFICIENCY}, too few to quote" if few else ""})
                continue
            value = _value(r, c)
            iqr = _value(r, c, c.iqr) if c.iqr and value else ""
            cells.append({"value": value or "–", "sub": f"({iqr})" if iqr else "", "cls": ""})
        rows.append(cells)
    return rows


# ------------------------------------------------------------------------------------------- figures


FULL_SIZE = (".png", ".svg")  # what an embedded figure links to, first found first


def _figure_files(fig_dir: Path, stem: str) -> tuple[list[dict], str]:
    """The files of one figure in ``figures/`` as relative links ({name, href}, sorted), and the link of the
    full-size image the embedded one opens (the PNG, else the SVG; "" when neither was written).  The report
    lies beside ``figures/`` (write_report's default place), so the links are relative to the campaign."""
    if not fig_dir.is_dir():
        return [], ""
    files = [{"name": p.name, "href": "figures/" + quote(p.name)}
             for p in sorted(fig_dir.glob(f"{glob.escape(stem)}.*")) if p.is_file() and p.stem == stem]
    by_suffix = {Path(f["name"]).suffix.lower(): f["href"] for f in files}
    return files, next((by_suffix[s] for s in FULL_SIZE if s in by_suffix), "")


def _figure_items(images: dict, scenario: str, trials: int, fig_dir: Path) -> list[dict]:
    items = []
    for kind in KINDS:
        stem = f"{kind}_{safe_name(scenario)}"
        if stem not in images:
            continue
        warning = ""
        if kind == "efficiency" and trials < MIN_TRIALS_EFFICIENCY:
            warning = (f"Only {trials} trials per calibrator: an efficiency needs about {MIN_TRIALS_EFFICIENCY} "
                       "or more before the point means much; read the intervals.")
        elif kind in ("convergence", "errors") and trials < FEW_TRIALS_CURVES:
            warning = f"Only {trials} trials per calibrator: medians and quartiles of so few runs are rough."
        files, full = _figure_files(fig_dir, stem)
        items.append({"data": base64.b64encode(images[stem]).decode("ascii"), "mime": "image/png",
                      "alt": f"{TITLES[kind]}, {scenario}", "title": f"{TITLES[kind]} — {scenario}",
                      "caption": CAPTIONS[kind], "warning": warning, "files": files, "full": full})
    return items


def _extra_figures(fig_dir: Path, images: dict | None = None) -> list[dict]:
    """The campaign-wide figures: the method comparison's (ECDF, anytime, profile) from ``images`` (drawn at
    screen resolution by ``make_figures``, each linked to its full-size file), then any other figure written
    into figures/ by others, embedded as it is."""

    images = images or {}
    items = []
    for stem in COMPARISON_KINDS:
        if stem in images:
            title, caption = EXTRA.get(stem, (stem.capitalize(), ""))
            files, full = _figure_files(fig_dir, stem)
            items.append({"data": base64.b64encode(images[stem]).decode("ascii"), "mime": "image/png", "alt": title,
                          "title": title, "caption": caption, "warning": "", "files": files, "full": full})
    if not fig_dir.is_dir():
        return items
    ours = re.compile("^(" + "|".join(KINDS) + ")_")
    for path in sorted(fig_dir.iterdir()):
        if ours.match(path.stem) or path.stem in images or path.suffix not in (".png", ".svg"):
            continue
        if path.suffix == ".svg" and path.with_suffix(".png").is_file():
            continue
        title, caption = EXTRA.get(path.stem, (path.stem.replace("_", " ").capitalize(), ""))
        mime = "image/png" if path.suffix == ".png" else "image/svg+xml"
        files, _ = _figure_files(fig_dir, path.stem)
        items.append({"data": base64.b64encode(path.read_bytes()).decode("ascii"), "mime": mime, "alt": title,
                      "title": title, "caption": caption, "warning": "", "files": files,
                      "full": "figures/" + quote(path.name)})
    return items


def _comparison_tables(campaign_dir: Path) -> list[dict]:
    """The method comparison's tables (benchmarks/comparison.py) per scenario: the expected running time to
    each target, the Holm-corrected paired tests and the win rates, as escaped HTML tables."""

    d = campaign_dir / "comparison"
    if not (d / "ert.csv").is_file():
        return []
    ert = pd.read_csv(d / "ert.csv")
    tests = pd.read_csv(d / "paired_tests.csv", keep_default_na=False) if (d / "paired_tests.csv").stat().st_size > 1 \
        else pd.DataFrame()
    out = []
    for scenario, part in ert.groupby("scenario", sort=False):
        part = part.assign(target_label=[(f"RMS ≤ {t:g}×") if k == "rms" else (f"angle ≤ {t:g}σ")
                                         for k, t in zip(part["kind"], part["target"])],
                           cell=[ert_cell(x) for x in part.itertuples(index=False)])
        order = list(dict.fromkeys(part["configuration"]))
        wide = part.pivot_table(index="configuration", columns="target_label", values="cell", aggfunc="first",
                                sort=False).reindex(order)
        item = {"name": scenario, "ert": wide.to_html(escape=True, border=0, classes="comparison",
                                                      index_names=False), "tests": ""}
        if len(tests):
            cols = ["a", "b", "n", "median_diff", "p_holm", "margin_nT", "verdict", "warning"]
            t = tests[tests["scenario"] == scenario][[c for c in cols if c in tests]]
            t = t.rename(columns={"a": "A", "b": "B", "n": "trials", "median_diff": "median A−B (nT)",
                                  "p_holm": "p (Holm)", "margin_nT": "practical margin (nT)", "verdict": "verdict",
                                  "warning": "note"})
            item["tests"] = t.to_html(escape=True, border=0, index=False, classes="comparison",
                                      float_format=lambda v: f"{v:.3g}")
        out.append(item)
    return out


def _failures(runs: pd.DataFrame) -> dict:
    if runs.empty:
        return {"head": "No runs.csv.", "rows": []}
    failed = runs[failed_mask(runs)]
    head = f"{len(failed)} of {len(runs)} runs failed."
    rows = []
    errors = failed["error"].astype(str).str.strip() if len(failed) else pd.Series(dtype=str)
    for text in pd.unique(errors):
        sel = failed[errors == text]
        where = sorted({f"{s} / {c}" for s, c in zip(sel.get("scenario", pd.Series("", index=sel.index)).fillna(""),
                                                      sel.get("configuration", pd.Series("", index=sel.index))
                                                      .fillna(""))})
        rows.append({"count": len(sel), "error": text, "where": where})
    return {"head": head, "rows": rows}


def _command_text(manifest: dict) -> str:
    cmd = manifest.get("command")
    if isinstance(cmd, (list, tuple)):
        return shlex.join(str(c) for c in cmd)
    return str(cmd) if cmd else ""


def _anchor(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_-]+", "-", name).strip("-") or "scenario"


# ----------------------------------------------------------------------------------------------- API


def render_report(campaign_dir: str | Path, images: dict | None = None, progress: bool = False) -> str:
    """The report's HTML text.  ``images`` ({figure stem: PNG bytes}, as ``make_figures(images=...)``
    fills it) saves drawing the figures again; without it they are drawn in memory."""
    from jinja2 import Environment, FileSystemLoader, select_autoescape
    from markupsafe import Markup

    campaign_dir = Path(campaign_dir)
    fig_dir = campaign_dir / "figures"
    read = read_manifest(campaign_dir / "manifest.json")  # a damaged one refused before any figure is drawn
    if images is None:
        images = {}
        make_figures(campaign_dir, formats=(), images=images, progress=progress)
    runs = _read_runs(campaign_dir)
    summary = _summary(campaign_dir, runs)
    manifest = read if read is not None else {}
    cols = _columns(summary)
    accept = "accept_rate" in summary
    styles = campaign_styles(campaign_dir, list(runs.get("configuration", [])))  # the figures' one style map
    ok = runs[~failed_mask(runs)] if len(runs) else runs
    trials = int(ok.groupby(["scenario", "configuration"]).size().min()) if len(ok) else 0

    scenarios = []
    names = list(dict.fromkeys(list(summary.get("scenario", [])) + list(runs.get("scenario", []))))
    for name in names:
        part = summary[summary["scenario"] == name] if len(summary) else summary
        n = int(ok[ok["scenario"] == name].groupby("configuration").size().min()) if len(ok) and \
            (ok["scenario"] == name).any() else 0
        warnings = []
        few = [r["configuration"] for _, r in part.iterrows() if _few(r)]
        if few:
            warnings.append(f"Efficiency from fewer than {MIN_TRIALS_EFFICIENCY} successful trials "
                            f"({', '.join(few)}): too few to quote; the 95 % interval under each value says how "
                            "little it is pinned down.")
        scenarios.append({"name": name, "anchor": _anchor(name), "description": _scenario_description(name),
                          "rows": _rows(part, cols, accept, styles), "warnings": warnings,
                          "figures": _figure_items(images, name, n, fig_dir)})

    configs = list(dict.fromkeys(summary.get("configuration", [])))
    n_failed = int(failed_mask(runs).sum()) if len(runs) else 0
    lede = (f"{len(runs)} runs: {len(names)} scenario{'s' if len(names) != 1 else ''} × {len(configs)} "
            f"calibrator configuration{'s' if len(configs) != 1 else ''} × {manifest.get('trials', trials)} trials"
            f"{f', {n_failed} failed' if n_failed else ''}; root seed {manifest.get('root_seed', '?')}.")
    warnings = [] if read is not None else [f"No manifest.json: {MANIFEST_UNKNOWNS}."]
    if manifest.get("complete") is False:
        warnings.append(f"The campaign is incomplete: {manifest.get('n_missing', '?')} runs are missing "
                        "(compare ... --resume completes it).")
    if len(runs) and trials < MIN_TRIALS_EFFICIENCY:
        warnings.append(f"Only {trials} successful trials per calibrator (fewer in places): efficiencies need about "
                        f"{MIN_TRIALS_EFFICIENCY} or more to be quoted; they are marked ⚠ and shown with their 95 % "
                        "bootstrap intervals.")
    if n_failed:
        warnings.append(f"{n_failed} runs failed and are left out of the medians (see Failed runs).")
    table_note = ("Medians over the finished runs, the inter-quartile range (IQR) underneath; under an "
                  "efficiency, its 95 % bootstrap interval. Wide tables scroll sideways. Each column is defined "
                  "in Column definitions below (also shown on hovering a column name).")
    skipped = [f"{s.get('scenario')} / {s.get('configuration')}: {s.get('reason')}"
               for s in manifest.get("skipped", []) if isinstance(s, dict)]
    env = Environment(loader=FileSystemLoader(str(TEMPLATES)), autoescape=select_autoescape(["html", "j2"]),
                      trim_blocks=False, lstrip_blocks=False, keep_trailing_newline=True)
    template = env.get_template("report.html.j2")
    return template.render(
        title=f"magbench campaign report — {campaign_dir.resolve().name}", lede=lede, warnings=warnings, css=Markup(CSS),
        scenarios=scenarios, columns=_header(summary, cols), table_note=table_note,
        extra_figures=_extra_figures(fig_dir, images), comparison=_comparison_tables(campaign_dir),
        failures=_failures(runs), skipped=skipped,
        command=_command_text(manifest), manifest=_manifest_rows(manifest))


def write_report(campaign_dir: str | Path, out: str | Path | None = None, images: dict | None = None,
                 progress: bool = False) -> Path:
    """Write the campaign's single-file HTML report and return its path."""
    campaign_dir = Path(campaign_dir)
    out = Path(out) if out is not None else campaign_dir / "report.html"
    page = render_report(campaign_dir, images=images, progress=progress)
    out.parent.mkdir(parents=True, exist_ok=True)
    return write_output(out, page)  # a link at report.html is replaced, not written through


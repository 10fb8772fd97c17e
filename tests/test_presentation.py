"""Tables, report, figures, help and packaging fit for a paper."""
from __future__ import annotations

import argparse
import contextlib
import io
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import tomllib

import magbench
from magbench.benchmarks.cli import build_parser, main
from magbench.benchmarks.figures import FORMATS, make_figures
from magbench.benchmarks.tables import MIN_TRIALS_EFFICIENCY, efficiency_interval, summarize, to_latex, to_markdown

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    """A tiny campaign: a turntable (lu2014) and random attitudes (cap9), a closed-form and an iterative method."""
    out = tmp_path_factory.mktemp("presentation") / "c"
    assert main(["compare", "--scenarios", "lu2014", "cap9", "--methods", "lsq", "ga:budget=400", "--trials", "3",
                 "--out", str(out), "--quiet", "--format", "png", "--dpi", "60"]) == 0
    return out


def _run(argv) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(argv)
    return code, out.getvalue(), err.getvalue()


# ---------------------------------------------------------------------------------------------- tables


def _markdown_tables(text: str) -> list[list[list[str]]]:
    """Every table of a Markdown text as rows of cell texts, parsed by markdown-it-py (GFM tables)."""
    markdown_it = pytest.importorskip("markdown_it")
    tokens = markdown_it.MarkdownIt("commonmark").enable("table").parse(text)
    tables, row, cell = [], None, None
    for t in tokens:
        if t.type == "table_open":
            tables.append([])
        elif t.type == "tr_open":
            row = []
        elif t.type in ("th_open", "td_open"):
            cell = ""
        elif t.type == "inline" and cell is not None:
            cell += t.content
        elif t.type in ("th_close", "td_close"):
            row.append(cell)
            cell = None
        elif t.type == "tr_close":
            tables[-1].append(row)
    return tables


def test_summary_markdown_parses_as_one_table(campaign):
    text = (campaign / "summary.md").read_text()
    tables = _markdown_tables(text)
    assert len(tables) == 1
    head, *rows = tables[0]
    n_lines = sum(1 for line in text.splitlines() if line.startswith("|"))
    assert len(rows) == n_lines - 2 == 4  # every line of the table became a row
    assert all(len(r) == len(head) for r in rows)
    assert "α error (arcsec)" in head and "efficiency" in head and "calibrator" in head
    assert not any("_" in h for h in head)  # human names, not snake_case
    # median (IQR) cells, and the too-few-trials mark on efficiencies from 3 trials
    assert re.fullmatch(r"[\d.e-]+ \([\d.e-]+\)", rows[0][head.index("α error (arcsec)")])
    assert rows[0][head.index("efficiency")].endswith("†")


def test_markdown_escapes_pipes_and_markup():
    summary = pd.DataFrame([{"scenario": "s|x", "configuration": "nlopt:algorithm=a|b <script>", "model": "nine",
                             "n_runs": 3, "success_rate": 1.0, "median_abs_alpha_err_arcsec": 1.5,
                             "iqr_abs_alpha_err_arcsec": 0.2}])
    (head, row), = _markdown_tables(to_markdown(summary))
    assert len(row) == len(head)
    assert row[0] == "s|x" and row[1] == "nlopt:algorithm=a|b &lt;script&gt;"  # shown, not run
    from markdown_it import MarkdownIt

    assert "<script>" not in MarkdownIt("commonmark").enable("table").render(to_markdown(summary))


def _latex_available() -> bool:
    if not shutil.which("pdflatex") or not shutil.which("kpsewhich"):
        return False
    found = subprocess.run(["kpsewhich", "booktabs.sty", "siunitx.sty", "adjustbox.sty"], capture_output=True,
                           text=True).stdout.split()
    return len(found) == 3


def test_latex_uses_booktabs_siunitx_caption_and_label(campaign):
    tex = (campaign / "summary.tex").read_text()
    for needle in (r"\toprule", r"\midrule", r"\bottomrule", r"S[table-format=", r"\caption{", r"\label{tab:",
                   "median", "IQR", r"\cmidrule"):
        assert needle in tex, needle
    assert r"\hline" not in tex and "|d$" not in tex and "''" not in tex
    assert tex.count(r"\begin{table}") >= 2  # split so that each fits the page width


@pytest.mark.skipif(not _latex_available(), reason="pdflatex with booktabs, siunitx and adjustbox not installed")
def test_latex_compiles_without_overfull_lines(campaign, tmp_path):
    shutil.copy(campaign / "summary.tex", tmp_path / "summary.tex")
    (tmp_path / "doc.tex").write_text("\\documentclass{article}\n\\usepackage[a4paper,margin=25mm]{geometry}\n"
                                      "\\usepackage{booktabs}\n\\usepackage{siunitx}\n\\usepackage{adjustbox}\n"
                                      "\\usepackage{textcomp}\n\\begin{document}\n\\input{summary.tex}\n"
                                      "\\end{document}\n")
    done = subprocess.run(["pdflatex", "-interaction=nonstopmode", "-halt-on-error", "doc.tex"], cwd=tmp_path,
                          capture_output=True, text=True, timeout=120)
    log = (tmp_path / "doc.log").read_text(errors="replace")
    assert done.returncode == 0, log[-3000:]
    assert (tmp_path / "doc.pdf").stat().st_size > 0
    assert "Overfull \\hbox" not in log


def test_latex_of_an_empty_summary_is_a_comment_only():
    assert to_latex(pd.DataFrame()).lstrip().startswith("%")


def test_efficiency_interval_covers_the_estimate_and_narrows_with_trials():
    rng = np.random.default_rng(1)
    widths = []
    for n in (8, 200):
        err, crb = rng.normal(0, 1, n), np.ones(n)
        lo, hi = efficiency_interval(err, crb)
        est = np.mean(crb ** 2) / np.mean(err ** 2)
        assert lo <= est <= hi
        widths.append(hi - lo)
    assert widths[1] < widths[0] / 2
    assert efficiency_interval(np.array([1.0]), np.array([1.0])) == (pytest.approx(np.nan, nan_ok=True),) * 2 or \
        all(np.isnan(efficiency_interval(np.array([1.0]), np.array([1.0]))))


def test_summary_carries_intervals_and_trial_counts(campaign):
    summary = pd.read_csv(campaign / "summary.csv")
    assert {"n_ok", "efficiency_min_angle_lo", "efficiency_min_angle_hi"} <= set(summary.columns)
    row = summary.dropna(subset=["efficiency_min_angle"]).iloc[0]
    assert row["efficiency_min_angle_lo"] <= row["efficiency_min_angle"] <= row["efficiency_min_angle_hi"]
    assert summarize(pd.read_csv(campaign / "runs.csv", keep_default_na=False, na_values=[""])
                     .assign(error=lambda d: d["error"].astype(object).fillna(""))).shape[0] == len(summary)


# ---------------------------------------------------------------------------------------------- report


def test_report_has_results_first_contents_and_too_few_trials_warnings(campaign):
    html = (campaign / "report.html").read_text()
    assert '<nav class="toc"' in html and 'href="#results"' in html and 'href="#figures"' in html
    assert html.index('id="results"') < html.index('id="figures"') < html.index('id="campaign"')
    assert html.index('id="results"') < html.index("Manifest")
    # the warning wherever trials are too few: page head, the tables and the efficiency figure
    assert "Only 3 successful trials per calibrator" in html
    assert html.count("Efficiency from fewer than") >= 2
    assert "an efficiency needs about" in html
    assert "median_abs_alpha_err_arcsec" not in html  # human column names
    assert "α error" in html
    # self-contained: embedded images, no external resources
    assert "data:image/png;base64," in html
    assert not re.search(r"""(src|href)=["']https?://""", html)


def test_report_escapes_labels(tmp_path, campaign):
    shutil.copytree(campaign, tmp_path / "c")
    runs = pd.read_csv(tmp_path / "c" / "runs.csv")
    runs.loc[runs["configuration"] == "lsq", "configuration"] = "<script>alert(1)</script>"
    runs.to_csv(tmp_path / "c" / "runs.csv", index=False)
    (tmp_path / "c" / "summary.csv").unlink()
    code, _, err = _run(["report", str(tmp_path / "c"), "--quiet"])
    assert code == 0, err
    html = (tmp_path / "c" / "report.html").read_text()
    assert "<script>" not in html and "&lt;script&gt;" in html


@pytest.mark.skipif(not shutil.which("chromium"), reason="chromium not installed")
def test_report_fits_1400_pixels_in_a_browser(campaign, tmp_path):
    """Headless Chromium lays the page out at 1400 px: nothing wider than the window (no sideways scrolling)."""
    probe = tmp_path / "probe.html"
    html = (campaign / "report.html").read_text()
    probe.write_text(html.replace("</body>", "<script>document.title = 'W' + document.documentElement.scrollWidth;"
                                             "</script></body>"))
    done = subprocess.run(["chromium", "--headless", "--no-sandbox", "--disable-gpu", "--window-size=1400,1000",
                           "--dump-dom", probe.as_uri()], capture_output=True, text=True, timeout=120)
    match = re.search(r"<title>W(\d+)</title>", done.stdout)
    assert match, done.stderr[-2000:]
    assert int(match.group(1)) <= 1400


# --------------------------------------------------------------------------------------------- figures


def test_figures_kinds_and_heading_only_where_there_is_one(campaign):
    names = {p.name for p in (campaign / "figures").iterdir()}
    for kind in ("errors", "accuracy_runtime", "convergence", "efficiency"):
        assert f"{kind}_lu2014.png" in names and f"{kind}_cap9.png" in names
    assert "field_heading_lu2014.png" in names
    assert "field_heading_cap9.png" not in names  # random attitudes: no heading to plot against


def test_traces_kept_for_every_trial(campaign):
    traces = pd.read_csv(campaign / "traces.csv")
    assert "trial" in traces.columns
    assert set(traces.loc[traces["configuration"] == "ga budget=400", "trial"]) == {0, 1, 2}
    assert traces.groupby(["scenario", "configuration", "trial"]).size().max() <= 100


def test_figures_in_each_format(campaign, tmp_path):
    """Every figure in each format, drawn once and saved in all three (one call: each figure is built once)."""
    written = make_figures(campaign, tmp_path, formats=FORMATS, dpi=40)
    for fmt in FORMATS:
        mine = [p for p in written if p.suffix == f".{fmt}"]
        assert mine and all(p.stat().st_size > 0 for p in mine)
        magic = {"png": b"\x89PNG", "pdf": b"%PDF", "svg": b"<?xml"}[fmt]
        assert all(p.read_bytes().startswith(magic) for p in mine), fmt
    assert {p.stem for p in written if p.suffix == ".png"} == {p.stem for p in written if p.suffix == ".pdf"} \
        == {p.stem for p in written if p.suffix == ".svg"}


def test_png_resolution_follows_dpi(campaign, tmp_path):
    from PIL import Image  # matplotlib's own dependency

    a = make_figures(campaign, tmp_path / "a", formats=("png",), dpi=50, kinds=("errors",))[0]
    b = make_figures(campaign, tmp_path / "b", formats=("png",), dpi=100, kinds=("errors",))[0]
    assert a.name == b.name and a.name.startswith("errors_")
    assert Image.open(b).size[0] == pytest.approx(2 * Image.open(a).size[0], abs=2)


def test_report_command_writes_figures_in_the_formats_asked(campaign, tmp_path):
    shutil.copytree(campaign, tmp_path / "c")
    shutil.rmtree(tmp_path / "c" / "figures")
    code, out, err = _run(["report", str(tmp_path / "c"), "--format", "pdf", "svg", "--quiet", "--json"])
    assert code == 0, err
    assert err == ""  # --quiet: no progress bar
    assert (tmp_path / "c" / "figures" / "errors_lu2014.pdf").is_file()
    assert (tmp_path / "c" / "figures" / "errors_lu2014.svg").is_file()
    assert not (tmp_path / "c" / "figures" / "errors_lu2014.png").exists()


def test_unknown_figure_format_is_refused(campaign, tmp_path):
    with pytest.raises(ValueError):
        make_figures(campaign, tmp_path, formats=("bmp",))
    assert _run(["report", str(campaign), "--format", "bmp"])[0] == 2


# -------------------------------------------------------------------------------------- help, packaging


def _subparsers():
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return parser, sub.choices


def test_every_option_of_every_command_has_a_help_line_and_its_default():
    parser, commands = _subparsers()
    assert {"compare", "report", "reproduce", "calibrate", "simulate", "diagnose", "list"} <= set(commands)
    for name, p in commands.items():
        text = p.format_help().split("\n\n", 1)[1]  # past the usage lines
        for action in p._actions:
            if isinstance(action, argparse._HelpAction):
                continue
            flag = action.option_strings[-1] if action.option_strings else action.metavar or action.dest
            block = re.search(re.escape(str(flag)) + r"[^\n]*\n?((?:\s{6,}[^\n]*\n?)*)", text)
            assert block, (name, flag)
            line = block.group(0)
            words = re.sub(r"\s+", " ", line.replace(str(flag), "", 1)).strip()
            assert len(words.split()) >= 2, f"{name} {flag}: no help text"
            if action.default not in (None, False, argparse.SUPPRESS) and action.option_strings:
                assert "default" in line.lower(), f"{name} {flag}: default {action.default!r} not shown"


def test_help_shows_defaults_of_compare():
    _, commands = _subparsers()
    text = re.sub(r"\s+", " ", commands["compare"].format_help())
    assert "(default: 10)" in text and "(default: png svg)" in text and "(default: 300)" in text
    assert "127.0.0.1" in text


def test_dask_local_runs_a_tiny_campaign(tmp_path):
    pytest.importorskip("distributed")
    out = tmp_path / "d"
    code, stdout, err = _run(["compare", "--scenarios", "lu2014", "--methods", "lsq", "--trials", "2", "--out",
                              str(out), "--dask", "local", "--jobs", "1", "--no-figures", "--json"])
    assert code == 0, err
    import json

    man = json.loads((out / "manifest.json").read_text())
    assert man["dask"] is True and man["n_runs"] == 2 and man["n_failed"] == 0
    assert json.loads(stdout)["n_runs"] == 2


def test_license_and_citation_match_the_package():
    yaml = pytest.importorskip("yaml")
    meta = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert meta["project"]["license"] == "MIT"
    license_text = (ROOT / "LICENSE").read_text()
    assert license_text.startswith("MIT License") and "2026 the magbench developers" in license_text
    cff = yaml.safe_load((ROOT / "CITATION.cff").read_text())
    assert cff["cff-version"] == "1.2.0"
    assert str(cff["version"]) == magbench.__version__
    assert cff["license"] == "MIT" and cff["title"] and cff["message"]
    assert cff["authors"] == [{"name": "magbench developers"}]
    import datetime

    released = datetime.date.fromisoformat(str(cff["date-released"]))  # a real date, not in the future
    assert datetime.date(2026, 11, 1) <= released <= datetime.date.today()


def test_report_template_ships_with_the_package():
    meta = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert "templates/*.j2" in meta["tool"]["setuptools"]["package-data"]["magbench.benchmarks"]
    assert (ROOT / "benchmarks" / "templates" / "report.html.j2").is_file()


def test_min_trials_constant_is_the_one_the_issue_names():
    assert MIN_TRIALS_EFFICIENCY == 30

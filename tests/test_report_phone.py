"""The campaign report on a phone: every table scrolls sideways in its own container so
that the page is never wider than a 390 px screen, every embedded figure links to its full-size file in
figures/, and the column definitions can be read without hovering."""
from __future__ import annotations

import html
import re
import shutil
import subprocess
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote

import pandas as pd
import pytest

from magbench.benchmarks.cli import main
from magbench.benchmarks.report import render_report

VOID = {"area", "base", "br", "col", "embed", "hr", "img", "input", "link", "meta", "source", "track", "wbr"}


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    """A small campaign: one turntable scenario, a closed-form and an iterative method (so the comparison's
    tables and figures are there too), 3 trials, figures at a low resolution."""
    out = tmp_path_factory.mktemp("phone") / "c"
    assert main(["compare", "--scenarios", "lu2014", "--methods", "lsq", "ga:budget=400", "--trials", "3",
                 "--out", str(out), "--quiet", "--format", "png", "--dpi", "40"]) == 0
    return out


def _images(campaign_dir: Path) -> dict:
    """The figures as render_report takes them, read back from figures/ instead of drawn again."""
    return {p.stem: p.read_bytes() for p in (campaign_dir / "figures").glob("*.png")}


@pytest.fixture(scope="module")
def failed(campaign, tmp_path_factory):
    """The campaign with three runs marked failed, one with a long error text: the failures table is drawn."""
    d = tmp_path_factory.mktemp("phone_failed") / "c"
    shutil.copytree(campaign, d)
    runs = pd.read_csv(d / "runs.csv", dtype={"error": str})
    runs.loc[[0, 1], "error"] = ("RuntimeError: the optimizer diverged after 12 iterations at "
                                 "/a/very/long/path/to/some/module_with_a_rather_long_name.py:123 (no finite value)")
    runs.loc[[4], "error"] = "ValueError: singular matrix"
    runs.to_csv(d / "runs.csv", index=False)
    (d / "summary.csv").unlink()  # summarized again from runs.csv
    return d


@pytest.fixture(scope="module")
def pages(campaign, failed) -> dict[str, tuple[Path, str]]:
    """{name: (campaign directory, report HTML)}: the report compare wrote, and one with failed runs."""
    return {"written": (campaign, (campaign / "report.html").read_text(encoding="utf-8")),
            "failed": (failed, render_report(failed, images=_images(failed)))}


# ------------------------------------------------------------------------------------------ structure


class _Elements(HTMLParser):
    """Every element of a page as (tag, attributes, ancestors, own text): ancestors as (tag, attributes)
    from the root down; own text is the text directly inside the element (not inside its children)."""

    def __init__(self):
        super().__init__(convert_charrefs=True)
        self.stack: list[list] = []
        self.elements: list[tuple[str, dict, list, list]] = []

    def handle_starttag(self, tag, attrs):
        record = (tag, dict(attrs), [(t, a) for t, a, _ in self.stack], [])
        self.elements.append(record)
        if tag not in VOID:
            self.stack.append([tag, record[1], record[3]])

    def handle_startendtag(self, tag, attrs):
        self.elements.append((tag, dict(attrs), [(t, a) for t, a, _ in self.stack], []))

    def handle_endtag(self, tag):
        for i in range(len(self.stack) - 1, -1, -1):
            if self.stack[i][0] == tag:
                del self.stack[i:]
                return

    def handle_data(self, data):
        if self.stack:
            self.stack[-1][2].append(data)


def _elements(page: str) -> list[tuple[str, dict, list, str]]:
    parser = _Elements()
    parser.feed(page)
    parser.close()
    return [(t, a, anc, re.sub(r"\s+", " ", "".join(text)).strip()) for t, a, anc, text in parser.elements]


def _is_scroller(tag: str, attrs: dict) -> bool:
    return (tag == "div" and "scroll" in (attrs.get("class") or "").split() and attrs.get("role") == "region"
            and attrs.get("tabindex") == "0" and bool((attrs.get("aria-label") or "").strip()))


def unwrapped_tables(page: str) -> list[dict]:
    """The tables of a page not inside a scrolling region (div.scroll, role region, focusable, labelled)."""
    return [a for t, a, anc, _ in _elements(page) if t == "table" and not any(_is_scroller(*x) for x in anc)]


def test_every_table_scrolls_in_its_own_labelled_region(pages):
    for name, (_, page) in pages.items():
        tables = [a for t, a, _, _ in _elements(page) if t == "table"]
        classes = {c for a in tables for c in (a.get("class") or "").split()}
        assert {"summary", "comparison", "manifest"} <= classes, name
        assert unwrapped_tables(page) == [], name
    assert "failures" in {c for t, a, _, _ in _elements(pages["failed"][1]) if t == "table"
                          for c in (a.get("class") or "").split()}


def test_wrapper_check_fails_on_unwrapped_tables(pages):
    """Negative control: the check finds bare tables, and tables in a plain div or an unlabelled scroller."""
    assert len(unwrapped_tables("<p>x</p><table><tr><td>1</td></tr></table>")) == 1
    assert len(unwrapped_tables('<div class="scroll"><table><tr><td>1</td></tr></table></div>')) == 1
    assert len(unwrapped_tables('<div class="scroll" role="region" tabindex="0" aria-label="">'
                                "<table><tr><td>1</td></tr></table></div>")) == 1
    page = pages["failed"][1]
    stripped = re.sub(r'<div class="scroll"[^>]*>', "<div>", page)
    n_tables = sum(1 for t, *_ in _elements(page) if t == "table")
    assert n_tables >= 4 and len(unwrapped_tables(stripped)) == n_tables


def _figure_links(page: str) -> list[tuple[str, str | None]]:
    """(alt text, href of the nearest enclosing link or None) of every <img>."""
    out = []
    for t, a, anc, _ in _elements(page):
        if t == "img":
            links = [x for tag, x in anc if tag == "a"]
            out.append((a.get("alt", ""), links[-1].get("href") if links else None))
    return out


def test_every_figure_links_to_its_full_size_file(pages):
    for name, (d, page) in pages.items():
        links = _figure_links(page)
        assert len(links) >= 8, name  # 5 kinds for a turntable, and the comparison's figures
        for alt, href in links:
            assert href and href.startswith("figures/"), (name, alt, href)
            assert (d / unquote(href)).is_file(), (name, alt, href)
        assert ("Angle errors relative to the Cramér-Rao bound, lu2014", "figures/errors_lu2014.png") in links
    assert "max-width:100%" in re.search(r"figure img\{[^}]*\}", pages["written"][1]).group(0)


def test_figure_links_follow_the_files_that_exist(campaign, tmp_path):
    """PNG first, the SVG when only that was written, no link when neither is there."""
    d = tmp_path / "c"
    shutil.copytree(campaign, d)
    images = _images(d)
    shutil.copy(d / "figures" / "errors_lu2014.png", d / "figures" / "errors_lu2014.svg")  # its content is no matter
    (d / "figures" / "errors_lu2014.png").unlink()
    (d / "figures" / "convergence_lu2014.png").unlink()
    links = dict(_figure_links(render_report(d, images=images)))
    assert links["Angle errors relative to the Cramér-Rao bound, lu2014"] == "figures/errors_lu2014.svg"
    assert links["Convergence over all trials, lu2014"] is None
    assert links["Accuracy against runtime, lu2014"] == "figures/accuracy_runtime_lu2014.png"


def test_column_definitions_visible_without_hovering(pages):
    for name, (_, page) in pages.items():
        elements = _elements(page)
        tips = {}
        for t, a, anc, text in elements:
            if t == "th" and "title" in a and any(tag == "table" and "summary" in (x.get("class") or "")
                                                  for tag, x in anc):
                tips[text] = a["title"]
        assert len(tips) >= 10 and {"calibrator", "α error", "efficiency", "runtime"} <= set(tips), name
        in_defs = [(t, text) for t, a, anc, text in elements if t in ("dt", "dd")
                   and any(tag == "details" and "defs" in (x.get("class") or "") for tag, x in anc)]
        terms = [text for t, text in in_defs if t == "dt"]
        definitions = dict(zip(terms, (text for t, text in in_defs if t == "dd")))
        assert len(terms) == len(set(terms))
        assert definitions == tips, name  # every header with a tip, defined by the same text
        assert "Column definitions" in page
        assert "Hover a column name" not in page
        note = next(text for t, a, _, text in elements if t == "p" and a.get("class") == "note")
        assert "Column definitions" in note, note


# -------------------------------------------------------------------------------------------- browser


def _layout(page: str, width: int, tmp_path: Path) -> tuple[int, int, list[str]]:
    """Headless Chromium lays the page out ``width`` CSS pixels wide, every <details> opened: (the window's
    inner width, document.documentElement.scrollWidth, the elements outside a scroller that stick out).

    The page is laid out in an iframe of that width (srcdoc, so the script may read it): headless Chromium's
    own window is never narrower than 500 px (at --window-size=390,900 window.innerWidth is 500), so sizing
    the window would measure a 500 px layout."""
    probe = tmp_path / f"probe{width}.html"
    script = ('document.getElementById("f").onload=function(){var w=this.contentWindow,d=w.document,o=[];'
              'd.querySelectorAll("details").forEach(function(x){x.open=true;});'
              'd.querySelectorAll("body *").forEach(function(e){var r=e.getBoundingClientRect();'
              'if(r.right>w.innerWidth+1&&!e.closest(".scroll"))o.push(e.tagName+"."+e.className);});'
              'document.title="W"+w.innerWidth+" S"+d.documentElement.scrollWidth+" "+o.slice(0,8).join(" ");};')
    probe.write_text(f'<!DOCTYPE html><html><head><meta charset="utf-8"><title>none</title></head>'
                     f'<body style="margin:0"><iframe id="f" style="width:{width}px;height:900px;border:0" '
                     f'srcdoc="{html.escape(page, quote=True)}"></iframe><script>{script}</script></body></html>',
                     encoding="utf-8")
    done = subprocess.run(["chromium", "--headless", "--no-sandbox", "--disable-gpu", "--window-size=1400,1000",
                           "--dump-dom", probe.as_uri()], capture_output=True, text=True, timeout=120)
    match = re.search(r"<title>W(\d+) S(\d+) ?(.*?)</title>", done.stdout, re.S)
    assert match, done.stderr[-2000:]
    return int(match.group(1)), int(match.group(2)), match.group(3).split()


@pytest.mark.skipif(not shutil.which("chromium"), reason="chromium not installed")
@pytest.mark.parametrize("width", [390, 1400])
def test_report_is_never_wider_than_the_window(pages, tmp_path, width):
    for name, (_, page) in pages.items():
        inner, scroll_width, sticking_out = _layout(page, width, tmp_path)
        assert inner == width, name  # laid out at the width asked
        assert scroll_width <= width, (name, scroll_width, sticking_out)
        assert sticking_out == [], name


@pytest.mark.skipif(not shutil.which("chromium"), reason="chromium not installed")
def test_width_probe_sees_a_table_that_does_not_scroll(pages, tmp_path):
    """Negative control: without the scrolling containers' overflow the summary table widens the page."""
    page = pages["failed"][1]
    assert ".scroll{overflow-x:auto" in page
    _, scroll_width, _ = _layout(page.replace(".scroll{overflow-x:auto", ".scroll{overflow-x:visible"),
                                 390, tmp_path)
    assert scroll_width > 390

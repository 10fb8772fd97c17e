"""One style per calibrator across every figure family (benchmarks/styles.py), every figure in every format,
and figures drawn in parallel identical to figures drawn serially."""
from __future__ import annotations

import hashlib
import itertools
import json

import matplotlib.colors as mcolors
import pytest

from magbench.benchmarks import comparison_figures
from magbench.benchmarks.cli import main
from magbench.benchmarks.figures import ALL_KINDS, BUILDER_OF, figure_tasks, make_figures
from magbench.benchmarks.styles import DISTINCT, PALETTE, campaign_styles, style_map

METHODS = ("lsq", "ga:budget=400", "ellipsoid", "twostep")


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    out = tmp_path_factory.mktemp("styles") / "c"
    assert main(["compare", "--scenarios", "lu2014", "sphere9", "--methods", *METHODS, "--trials", "3",
                 "--out", str(out), "--quiet", "--format", "png", "--dpi", "30"]) == 0
    return out


def test_up_to_twenty_four_methods_have_distinct_styles():
    names = [f"m{i}" for i in range(DISTINCT)]
    styles = style_map(names)
    markers = {s["marker"] for s in styles.values()}
    lines = {(s["color"], s["ls"]) for s in styles.values()}
    assert len(markers) == len(lines) == DISTINCT == 24  # 17 in the reproduced campaign
    assert "#F0E442" not in PALETTE  # the low-contrast yellow is not a line colour


def test_the_map_follows_the_campaign_order_not_the_figure(campaign):
    """A figure that shows only some methods still gives each the campaign's style: the map is built from
    the manifest's configuration list (negative control: a map from a subset differs)."""
    listed = json.loads((campaign / "manifest.json").read_text())["campaign"]["configurations"]
    styles = campaign_styles(campaign)
    assert list(styles) == listed
    subset = style_map(sorted(listed[1:]))
    assert any(subset[c] != styles[c] for c in subset)  # what per-figure maps used to do


def _drawn_colours(fig) -> dict[str, str]:
    """Legend label -> colour of its handle, over the figure's legends (figure-level and axes-level)."""
    legends = list(fig.legends) + [ax.get_legend() for ax in fig.axes if ax.get_legend() is not None]
    out = {}
    for legend in legends:
        for handle, text in zip(legend.legend_handles, legend.get_texts()):
            get = getattr(handle, "get_color", None) or getattr(handle, "get_facecolor", None)
            if get is not None:
                out[text.get_text()] = mcolors.to_hex(get())
    return out


def test_every_family_draws_each_method_in_its_campaign_colour(campaign):
    styles = campaign_styles(campaign)
    checked = set()
    for kind, scenario, data in figure_tasks(campaign):
        fig = comparison_figures.BUILDERS[kind](data, styles) if scenario is None else BUILDER_OF[kind](data, scenario, styles)
        if fig is None:
            continue
        for label, colour in _drawn_colours(fig).items():
            conf = next((c for c in styles if label == c or label.startswith(c + " (")), None)
            if conf is not None:
                assert colour == mcolors.to_hex(styles[conf]["color"]), (kind, label)
                checked.add(kind)
    assert {"convergence", "accuracy_runtime", "ecdf", "anytime", "profile"} <= checked


def test_every_figure_in_every_requested_format(campaign, tmp_path):
    """The comparison's figures too (anytime, ecdf and profile were missing from --format svg), in each format
    asked (svg and pdf, one report: each figure built once)."""
    assert main(["report", str(campaign), "--format", "svg", "pdf", "--quiet"]) == 0
    expected = {p.stem for p in (campaign / "figures").glob("*.png")}
    for fmt in ("svg", "pdf"):
        written = {p.stem for p in (campaign / "figures").glob(f"*.{fmt}")}
        assert {"anytime", "ecdf", "profile"} <= written, fmt
        assert written == expected, fmt


def test_parallel_figures_are_the_serial_figures(campaign, tmp_path):
    one = make_figures(campaign, tmp_path / "one", formats=("png", "svg"), dpi=30, jobs=1)
    two = make_figures(campaign, tmp_path / "two", formats=("png", "svg"), dpi=30, jobs=2)
    assert [p.name for p in one] == [p.name for p in two] and len(one) >= 2 * 10

    def digest(p):
        return hashlib.sha256(p.read_bytes()).hexdigest()

    assert [digest(p) for p in one] == [digest(p) for p in two]
    kinds = {p.stem.split("_")[0] if p.stem not in ALL_KINDS else p.stem for p in one}
    assert {"ecdf", "anytime", "profile"} <= kinds


def test_markers_and_palette_cycle_beyond_the_distinct_range():
    styles = style_map([f"m{i}" for i in range(DISTINCT + 2)])
    first, again = styles["m0"], styles[f"m{DISTINCT}"]
    assert first["marker"] == again["marker"]  # documented repetition past DISTINCT
    assert len({(s["color"], s["marker"], s["ls"]) for s in itertools.islice(styles.values(), DISTINCT)}) == DISTINCT


def test_the_report_shows_each_calibrator_in_its_figure_colour(campaign):
    import re

    html = (campaign / "report.html").read_text()
    shown = {name.strip(): (colour, marker, ls) for colour, marker, ls, name in
             re.findall(r'<svg class="swatch"[^>]* data-colour="(#[0-9A-Fa-f]{6})" data-marker="([^"]+)" '
                        r'data-ls="([^"]+)">.*?</svg>([^<]+)<', html)}
    styles = campaign_styles(campaign)
    assert shown and all(shown[c] == (styles[c]["color"], styles[c]["marker"], styles[c]["ls"]) for c in shown)
    assert set(shown) == set(styles)


def test_the_report_tells_apart_methods_that_share_a_colour():
    """Beyond the palette's eight colours two configurations share a colour (aga and nlopt in the reproduced
    campaign): the report's swatch shows the marker and line style too, each drawn as in the figures."""
    import re

    from magbench.benchmarks.styles import swatch_svg

    styles = style_map([f"m{i}" for i in range(DISTINCT)])
    svgs = {n: swatch_svg(st, n) for n, st in styles.items()}
    assert len(set(svgs.values())) == DISTINCT
    assert styles["m0"]["color"] == styles["m8"]["color"] and svgs["m0"] != svgs["m8"]
    for n, svg in svgs.items():
        assert re.fullmatch(r'<svg class="swatch" [^<]*><line [^<]*/><path d="M[^"]+"[^<]*/></svg>', svg), n


def test_every_style_draws_as_a_format_string_too():
    """errorbar's fmt parses the marker: every marker of the map must be a format-string code (a mathtext
    marker broke the 16th method's accuracy-runtime point)."""
    from matplotlib.figure import Figure

    ax = Figure().subplots()
    for st in style_map([f"m{i}" for i in range(DISTINCT)]).values():
        ax.errorbar([1.0], [1.0], yerr=[[0.1], [0.1]], fmt=st["marker"], color=st["color"])
        ax.plot([1.0, 2.0], [1.0, 2.0], st["ls"] + st["marker"], color=st["color"])


def test_direct_labels_never_overlap_even_where_points_coincide():
    import numpy as np
    from matplotlib.figure import Figure

    from magbench.benchmarks.figures import _direct_labels

    fig = Figure(figsize=(8.5, 4.8))
    ax = fig.subplots()
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.plot([1e-4, 1e-1], [0.5, 1e3], alpha=0)
    rng = np.random.default_rng(0)
    points = [(f"method{i}", 3e-4, 1.1, "k") for i in range(12)]  # twelve on one spot
    points += [(f"m{i}", 3e-4 * (1 + 1e-9 * i), 1.1 + 1e-12 * i, "k") for i in range(6)]  # float-close ones
    points += [(f"p{i}", float(10 ** rng.uniform(-4, -1)), float(10 ** rng.uniform(0, 3)), "k") for i in range(10)]
    _direct_labels(ax, points)  # returns (it once looped forever on labels a rounding error apart)
    offsets = {a.get_text(): a.xyann[1] for a in ax.texts}
    same_spot = sorted(offsets[f"method{i}"] for i in range(12))
    assert all(b - a >= 7.5 + 1.9 for a, b in zip(same_spot, same_spot[1:]))  # stacked, one line apart


def test_line_markers_are_drawn_in_the_errors_figure(campaign):
    """Styles 16 and on use line markers (+, x, 1-4, |, _), which are only an edge: the single-run points of
    the angle-error figure were drawn with no line width, so ttls ('+') and twostep ('x') had no points in a
    17-method campaign.  Every scatter of a line marker must have a width."""
    from matplotlib.collections import PathCollection
    from matplotlib.markers import MarkerStyle

    configs = list(campaign_styles(campaign))
    markers = ("+", "x", "o", "1")
    styles = {c: {"color": PALETTE[i], "marker": markers[i], "ls": "-"} for i, c in enumerate(configs)}
    seen = set()
    for kind, scenario, data in figure_tasks(campaign, kinds=("errors",)):
        fig = BUILDER_OF[kind](data, scenario, styles)
        for ax in fig.axes:
            for coll in ax.collections:
                if not isinstance(coll, PathCollection) or not len(coll.get_offsets()):
                    continue
                colour = mcolors.to_hex(coll.get_facecolors()[0], keep_alpha=False)
                conf = next(c for c in configs if mcolors.to_hex(styles[c]["color"]) == colour)
                if not MarkerStyle(styles[conf]["marker"]).is_filled():
                    assert max(coll.get_linewidths()) > 0, (scenario, conf, styles[conf]["marker"])
                    seen.add(styles[conf]["marker"])
    assert {"+", "x", "1"} <= seen


def test_the_raw_readings_curve_is_no_method_s_colour(campaign):
    """The heading figure's 'before' curve was near-black beside ga's black line: it is a grey no method
    has."""
    styles = campaign_styles(campaign)
    tasks = [t for t in figure_tasks(campaign, kinds=("field_heading",))]
    assert tasks
    for kind, scenario, data in tasks:
        fig = BUILDER_OF[kind](data, scenario, styles)
        before = [ln for ln in fig.axes[0].get_lines() if ln.get_label() == "before (raw readings)"]
        assert len(before) == 1
        grey = mcolors.to_hex(before[0].get_color())
        assert all(mcolors.to_hex(c) != grey for c in PALETTE) and grey not in ("#000000", "#404040")


def test_leaders_of_stacked_labels_stay_clear_of_the_other_names():
    """Where points crowd side by side, the label of a point further left sits higher and its leader ends at
    the label's lower-left corner: it passes left of the names below it (leaders used to run to the middle
    of their label, across the names stacked beneath)."""
    from matplotlib.figure import Figure

    from magbench.benchmarks.figures import _direct_labels

    fig = Figure(figsize=(8.5, 4.8))
    ax = fig.subplots()
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.plot([1e-4, 1e-1], [0.5, 1e3], alpha=0)
    points = [(name, 3e-4 * (1 + 0.04 * i), 1.1 + 0.001 * (i % 2), "k")
              for i, name in enumerate(["tls", "merayo", "ellipsoid", "sym", "ttls"])]
    _direct_labels(ax, points)
    rise = {a.get_text(): a.xyann[1] for a in ax.texts}
    heights = [rise[name] for name, *_ in points]  # left to right
    assert all(a > b for a, b in zip(heights, heights[1:]))
    assert all(a.arrowprops["relpos"] == (0.0, 0.0) for a in ax.texts if a.arrowprops)


def test_no_label_lies_across_another_labels_leader():
    """The crowd of results/campaign's accuracy-runtime figure: ttls, just left of twostep, was written
    across the leader of twostep's label (pushed up by lsq's). Every label box is now clear of every
    leader (the near-vertical line from a pushed label's point to its lower-left corner)."""
    from magbench.benchmarks.figures import LABEL_GAP_PT, place_labels

    font = 7.5
    items = [("tls", 10.0, 50.0), ("merayo", 14.0, 50.5), ("ellipsoid", 18.0, 50.2), ("sym", 20.0, 50.0),
             ("ttls", 26.0, 50.1), ("twostep", 34.0, 50.3), ("lsq", 60.0, 50.0), ("nlopt", 150.0, 50.0)]
    rises = place_labels(items, font)
    boxes = [(px + LABEL_GAP_PT, px + LABEL_GAP_PT + 0.55 * font * len(n), py + dy, py + dy + font)
             for (n, px, py), dy in zip(items, rises)]
    leaders = [(j, px, px + LABEL_GAP_PT, py, py + dy + 3) for j, ((_, px, py), dy) in enumerate(zip(items, rises))
               if dy > font]
    assert leaders  # the crowd pushes some labels away from their points
    for i, (x0, x1, y0, y1) in enumerate(boxes):
        for j, a, b, lo, hi in leaders:
            if j != i:  # another label's leader never runs through this label
                assert not (a <= x1 and b >= x0 and y0 < hi - 0.01 and y1 > lo + 0.01), (items[i][0], items[j][0])
        for k, (u0, u1, v0, v1) in enumerate(boxes):
            if k != i:  # no two labels overlap
                assert not (u0 < x1 - 8 and u1 > x0 + 8 and v0 < y1 - 0.5 and v1 > y0 + 0.5) or \
                    abs(items[i][1] - items[k][1]) >= max(x1 - x0, u1 - u0) + 8, (items[i][0], items[k][0])


def test_log_tick_labels_are_plain_text_not_mathtext():
    """log_scale's labels: 10⁻³ and 2×10⁻³ in Unicode (mathtext's parse was a fifth of the drawing time);
    the control: matplotlib's own formatter writes the same numbers as mathtext."""
    from matplotlib.figure import Figure
    from matplotlib.ticker import LogFormatterSciNotation

    from magbench.benchmarks.styles import log_scale

    ax = Figure().subplots()
    ax.plot([1e-3, 5e2], [2e-3, 4e-3])
    log_scale(ax, "x", "y")
    ax.set_ylim(1.5e-3, 6e-3)
    major = ax.xaxis.get_major_formatter()
    major.set_locs([1e-3, 1.0, 1e2])
    assert [major(v) for v in (1e-3, 1.0, 1e2)] == ["10⁻³", "10⁰", "10²"]
    minor = ax.yaxis.get_minor_formatter()
    minor.set_locs([2e-3, 3e-3])
    assert minor(2e-3) == "2×10⁻³"
    plain = LogFormatterSciNotation()
    plain.set_axis(ax.xaxis)
    plain.set_locs([1e-3])
    assert plain(1e-3) == "$\\mathdefault{10^{-3}}$"

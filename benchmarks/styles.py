"""One look for every figure of a campaign: a style per calibrator configuration (colour, marker, line
style) taken from the campaign's full configuration list, and the fonts, sizes and file settings that
every figure family (``figures.py``, ``comparison_figures.py``) and the report share.

The style map is built once per campaign from the order in which the campaign lists its configurations
(``manifest.json``: ``campaign.configurations``), never from the set of names a single figure happens to
show, so that a method keeps its colour from the convergence plot to the ECDF to the report.  Up to
``DISTINCT`` configurations no two share the (colour, marker, line style) triple, and no two share both
colour and marker; the palette is Okabe & Ito's colour-blind-safe set with its low-contrast yellow
replaced by Tol's wine.
"""
from __future__ import annotations

import functools
import json
import re
from pathlib import Path

PALETTE = ("#0072B2", "#D55E00", "#009E73", "#CC79A7", "#E69F00", "#56B4E9", "#000000", "#882255")
"""Okabe-Ito blue, vermillion, bluish green, reddish purple, orange, sky blue, black; Tol's wine (#882255)
instead of Okabe-Ito's yellow (#F0E442), which is unreadable as a line on white."""
LINESTYLES = ("-", "--", ":")
MARKERS = ("o", "s", "D", "^", "v", "P", "X", "<", ">", "*", "h", "p", "d", "H", "8", "+", "x", "1", "2", "3", "4",
           "|", "_", ".")
"""Marker codes every matplotlib call takes, including ``errorbar``'s ``fmt`` string (a mathtext marker is
not a format string)."""
DISTINCT = len(MARKERS)
"""Configurations with pairwise distinct styles; beyond this the styles repeat in the same order."""
BOUND_GREY = "0.5"  # the Cramér-Rao bound and other references: neutral grey, never a method's colour
WARN_COLOUR = "#B8860B"
SVG_SALT = "magbench"
FONT_SIZE = 9
RC = {"svg.hashsalt": SVG_SALT, "svg.fonttype": "path", "figure.dpi": 100, "savefig.dpi": 300,
      "pdf.fonttype": 42, "axes.grid": True, "grid.alpha": 0.3, "font.size": FONT_SIZE, "axes.labelsize": FONT_SIZE,
      "xtick.labelsize": FONT_SIZE - 1, "ytick.labelsize": FONT_SIZE - 1, "legend.fontsize": FONT_SIZE - 1,
      "legend.title_fontsize": FONT_SIZE, "axes.titlesize": FONT_SIZE + 1, "figure.titlesize": FONT_SIZE + 1,
      "mathtext.default": "regular"}
"""The settings of every figure: one font size for labels, one a point smaller for ticks and legends, one a
point larger for titles; mathtext in the text font; SVG with a fixed hash salt and text as paths."""


def style_map(configurations) -> dict[str, dict]:
    """``{configuration: {"color", "marker", "ls"}}`` in the given order: the i-th configuration gets
    colour ``i mod 8``, line style ``i div 8`` and marker ``i``, so that the first ``DISTINCT`` (24) are
    pairwise distinct in marker and in (colour, line style).  Repeated names keep their first style."""
    out: dict[str, dict] = {}
    for name in configurations:
        name = str(name)
        if name in out:
            continue
        i = len(out)
        out[name] = {"color": PALETTE[i % len(PALETTE)], "marker": MARKERS[i % len(MARKERS)],
                     "ls": LINESTYLES[(i // len(PALETTE)) % len(LINESTYLES)]}
    return out


def campaign_configurations(campaign_dir, *seen) -> list[str]:
    """The campaign's configurations in its own order (the manifest's campaign definition), followed by any
    other name found in ``seen`` (iterables of names, e.g. runs.csv's column) in order of first appearance."""
    names: list[str] = []
    try:
        manifest = json.loads((Path(campaign_dir) / "manifest.json").read_text(encoding="utf-8"))
        listed = manifest.get("campaign", {}).get("configurations", []) if isinstance(manifest, dict) else []
        names = [str(n) for n in listed] if isinstance(listed, list) else []
    except (OSError, ValueError, AttributeError):
        names = []
    for series in seen:
        for n in series:
            if str(n) not in names:
                names.append(str(n))
    return names


def campaign_styles(campaign_dir, *seen) -> dict[str, dict]:
    """The campaign's one style map (``style_map`` of ``campaign_configurations``)."""
    return style_map(campaign_configurations(campaign_dir, *seen))


def swatch_svg(style: dict, title: str = "") -> str:
    """A small inline SVG of a configuration's style for an HTML table: a stretch of its line (colour, line
    style) with its marker in the middle, so that two configurations sharing a colour (beyond the eight of
    the palette) are told apart in the report as in the figures.  ``data-colour`` and ``data-marker`` carry
    the style for checks."""
    from html import escape

    from matplotlib.markers import MarkerStyle

    colour, marker, ls = str(style.get("color", "#000000")), str(style.get("marker", "o")), str(style.get("ls", "-"))
    m = MarkerStyle(marker)
    path = m.get_path().transformed(m.get_transform())
    codes = {1: "M", 2: "L", 3: "Q", 4: "C"}
    d = []
    scale = 9.0  # a marker of unit size fills three quarters of the line height
    for vertices, code in path.iter_segments(simplify=False, curves=True):
        if code == 79:  # CLOSEPOLY
            d.append("Z")
            continue
        pts = " ".join(f"{scale * x:.2f} {-scale * y:.2f}" for x, y in vertices.reshape(-1, 2))
        d.append(f"{codes.get(int(code), 'L')}{pts}")
    filled = m.is_filled()
    dash = {"--": ' stroke-dasharray="4 2"', ":": ' stroke-dasharray="1.2 1.8"', "-.": ' stroke-dasharray="4 1.5 1 1.5"'}
    return (f'<svg class="swatch" width="2.2em" height="1em" viewBox="-13 -6 26 12" role="img" '
            f'aria-label="{escape(title or "style")}" data-colour="{escape(colour)}" data-marker="{escape(marker)}" '
            f'data-ls="{escape(ls)}"><line x1="-12" y1="0" x2="12" y2="0" stroke="{escape(colour)}" '
            f'stroke-width="1.4"{dash.get(ls, "")}/><path d="{" ".join(d)}" '
            f'fill="{escape(colour) if filled else "none"}" stroke="{escape(colour)}" '
            f'stroke-width="{0.6 if filled else 1.3}"/></svg>')


_SUPERSCRIPT = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")
_MATHTEXT_LABEL = re.compile(r"^\$\\mathdefault\{(?P<body>.*)\}\$$")


@functools.cache
def _plain_log_formatter():
    """matplotlib's ``LogFormatterSciNotation`` with its labels in plain text: ``10⁻³``, ``2×10⁻³``, ``1``
    (a label it would write another way is kept as mathtext)."""
    from matplotlib.ticker import LogFormatterSciNotation

    class PlainLogFormatter(LogFormatterSciNotation):
        def __call__(self, x, pos=None):
            text = super().__call__(x, pos)
            match = _MATHTEXT_LABEL.match(text)
            if match is None:
                return text
            body = re.sub(r"\^\{(-?\d+)\}", lambda m: m.group(1).translate(_SUPERSCRIPT),
                          match.group("body").replace(r"\times", "×"))
            return text if any(c in body for c in "\\{}^$") else body

    return PlainLogFormatter


def log_scale(ax, *axes: str) -> None:
    """A log scale on each of ``axes`` (``"x"``, ``"y"``) of ``ax``, its tick labels in plain text with
    Unicode superscripts (``10⁻³``) instead of mathtext: parsing the mathtext labels (pyparsing, once per
    label and resolution) was a fifth of the figures' time, and the labels look the same."""
    formatter = _plain_log_formatter()
    for name in axes:
        getattr(ax, f"set_{name}scale")("log")
        axis = getattr(ax, f"{name}axis")
        axis.set_major_formatter(formatter())
        axis.set_minor_formatter(formatter(labelOnlyBase=False))

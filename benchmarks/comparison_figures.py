"""Figures of the method comparison (``benchmarks/comparison.py``): runtime ECDFs, anytime curves and
performance profiles, one panel per scenario, one colour per method (the Okabe-Ito colour-blind-safe
palette, in a fixed order so that a method keeps its colour across figures)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

OKABE_ITO = ("#0072B2", "#E69F00", "#009E73", "#D55E00", "#CC79A7", "#56B4E9", "#F0E442", "#000000")
LINESTYLES = ("-", "--", ":", "-.")
MARK_EVERY = 6
"""A marker on every sixth point of a curve, so that methods sharing a colour stay apart."""


def style_of(names: list[str]) -> dict:
    """A (colour, line style) per method name, stable for the same sorted set of names."""
    return {n: (OKABE_ITO[i % len(OKABE_ITO)], LINESTYLES[(i // len(OKABE_ITO)) % len(LINESTYLES)])
            for i, n in enumerate(sorted(names))}


def _panels(n: int):
    from matplotlib.figure import Figure

    cols = min(n, 2)
    rows = int(np.ceil(n / cols))
    fig = Figure(figsize=(6.2 * cols, 3.9 * rows), layout="constrained")
    axes = fig.subplots(rows, cols, squeeze=False).ravel()
    for ax in axes[n:]:
        ax.set_visible(False)
    return fig, axes


def _save(fig, path: Path, fmt: str, dpi: int) -> Path:
    """``path`` with the format's suffix, through the campaign figures' writer (no dates or software tags)."""
    from magbench.benchmarks.figures import _save as save_formats

    return save_formats(fig, path.parent, path.name, (fmt,), dpi)[0]


def comparison_figures(campaign_dir, curves: pd.DataFrame, anytime: pd.DataFrame, profile: pd.DataFrame,
                       fmt: str = "png", dpi: int = 150) -> list[Path]:
    out = Path(campaign_dir) / "figures"
    out.mkdir(exist_ok=True)
    from magbench.benchmarks.figures import method_styles

    names = sorted(set(curves.get("configuration", [])) | set(anytime.get("configuration", []))
                   | set(profile.get("configuration", [])))
    styles = method_styles(names)  # colour, line style and a marker per method (more than eight stay distinct)
    written = []
    if len(curves):
        written.append(_ecdf_figure(curves, styles, out / "ecdf", fmt, dpi))
    if len(anytime):
        written.append(_anytime_figure(anytime, styles, out / "anytime", fmt, dpi))
    if len(profile):
        written.append(_profile_figure(profile, styles, out / "profile", fmt, dpi))
    return written


def _scenario_figure(frame, styles, draw, ylabel: str, title: str, legend_loc: str, log_y: bool = False):
    """One panel per scenario of ``frame``, ``draw(ax, part, conf, style)`` once per configuration, on a
    log axis of objective evaluations."""
    scenarios = list(dict.fromkeys(frame["scenario"]))
    fig, axes = _panels(len(scenarios))
    for ax, scenario in zip(axes, scenarios):
        for conf, part in frame[frame["scenario"] == scenario].groupby("configuration", sort=False):
            draw(ax, part, conf, styles[conf])
        if log_y:
            ax.axhline(1.0, color="0.5", lw=1, ls="--")
        ax.set_xscale("log")
        if log_y:
            ax.set_yscale("log")
        else:
            ax.set_ylim(-0.02, 1.02)
        ax.set_xlabel("objective evaluations")
        ax.set_ylabel(ylabel)
        ax.set_title(f"{scenario}: {title}", fontsize=10)
        ax.grid(True, which="major", alpha=0.3)
        ax.legend(fontsize=7, loc=legend_loc)
    return fig


def _ecdf_figure(curves, styles, path, fmt, dpi):
    def draw(ax, part, conf, st):
        ax.step(part["evaluations"], part["fraction"], where="post", color=st["color"], ls=st["ls"], label=conf,
                marker=st["marker"], markevery=MARK_EVERY, ms=4)

    fig = _scenario_figure(curves, styles, draw, "fraction of (run, target) pairs reached",
                           "runtime ECDF, RMS targets 10x .. 1.001x optimum", "lower right")
    return _save(fig, path, fmt, dpi)


def _anytime_figure(anytime, styles, path, fmt, dpi):
    def draw(ax, part, conf, st):
        ax.plot(part["evaluations"], part["median"], color=st["color"], ls=st["ls"], marker=st["marker"],
                markevery=MARK_EVERY, ms=4, label=f"{conf} (n={part['n'].max()})")
        ax.fill_between(part["evaluations"], part["q25"], part["q75"], color=st["color"], alpha=0.15, lw=0)

    fig = _scenario_figure(anytime, styles, draw, "best RMS so far / optimum",
                           "anytime performance (median, inter-quartile band)", "upper right", log_y=True)
    return _save(fig, path, fmt, dpi)


def _profile_figure(profile, styles, path, fmt, dpi):
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6.2, 3.9), layout="constrained")
    ax = fig.subplots()
    for conf, part in profile.groupby("configuration", sort=False):
        st = styles[conf]
        ax.step(part["tau"], part["fraction"], where="post", color=st["color"], ls=st["ls"], marker=st["marker"],
                markevery=MARK_EVERY, ms=4, label=conf)
    ax.set_xscale("log")
    ax.set_ylim(-0.02, 1.02)
    ax.set_xlabel("tau: ERT (evaluations) to 1.01 x optimum within tau x the best method's")
    ax.set_ylabel("fraction of scenarios")
    ax.set_title("Performance profile (Dolan & Moré) across scenarios", fontsize=10)
    ax.grid(True, which="major", alpha=0.3)
    ax.legend(fontsize=7, loc="lower right")
    return _save(fig, path, fmt, dpi)

"""Figures of the method comparison (``benchmarks/comparison.py``): runtime ECDFs, anytime curves and
performance profiles, one panel per scenario.  Each builder takes the comparison's table (read from
``comparison/*.csv``) and the campaign's style map (``benchmarks.styles.campaign_styles``) and returns a
``Figure``; ``benchmarks.figures.make_figures`` draws them with the other families, in every format."""
from __future__ import annotations

import numpy as np
import pandas as pd
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from magbench.benchmarks.styles import BOUND_GREY, log_scale

MARK_EVERY = 6
"""A marker on every sixth point of a curve, so that methods sharing a colour stay apart."""
COMPARISON_KINDS = ("ecdf", "anytime", "profile")


def _panels(n: int) -> tuple[Figure, np.ndarray]:
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    cols = min(n, 2)
    rows = int(np.ceil(n / cols))
    fig = Figure(figsize=(5.2 * cols + 2.2, 3.6 * rows), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(rows, cols, squeeze=False).ravel()
    for ax in axes[n:]:
        ax.set_visible(False)
    return fig, axes


def _legend(fig: Figure, confs: list[str], styles: dict, label=None) -> None:
    """One legend for all panels, outside the data and the titles (right of the panels)."""
    handles = [Line2D([], [], color=styles[c]["color"], ls=styles[c]["ls"], marker=styles[c]["marker"], ms=5,
                      label=label(c) if label else c) for c in confs]
    fig.legend(handles=handles, loc="outside right upper", title="calibrator")


def _in_order(frame: pd.DataFrame, styles: dict) -> list[str]:
    """The configurations of ``frame`` in the campaign's order (the style map's)."""
    present = set(frame["configuration"])
    return [c for c in styles if c in present]


def _scenario_figure(frame: pd.DataFrame, styles: dict, draw, ylabel: str, title: str,
                     log_y: bool = False) -> Figure:
    """One panel per scenario of ``frame``, ``draw(ax, part, style)`` once per configuration, on a log axis
    of objective evaluations."""
    scenarios = list(dict.fromkeys(frame["scenario"]))
    fig, axes = _panels(len(scenarios))
    confs = _in_order(frame, styles)
    for ax, scenario in zip(axes, scenarios):
        here = frame[frame["scenario"] == scenario]
        for conf in confs:
            part = here[here["configuration"] == conf]
            if len(part):
                draw(ax, part, styles[conf])
        if log_y:
            ax.axhline(1.0, color=BOUND_GREY, lw=1, ls="--")
            log_scale(ax, "y")
        else:
            ax.set_ylim(-0.02, 1.02)
        log_scale(ax, "x")
        ax.set_xlabel("objective evaluations")
        ax.set_ylabel(ylabel)
        ax.set_title(scenario)
    fig.suptitle(title)
    _legend(fig, confs, styles)
    return fig


def fig_ecdf(curves: pd.DataFrame, styles: dict) -> Figure | None:
    """Fraction of (run, target) pairs reached against evaluations (COCO's runtime ECDF)."""
    if curves.empty:
        return None

    def draw(ax, part, st):
        ax.step(part["evaluations"], part["fraction"], where="post", color=st["color"], ls=st["ls"],
                marker=st["marker"], markevery=MARK_EVERY, ms=4)

    return _scenario_figure(curves, styles, draw, "fraction of (run, target) pairs reached",
                            "Runtime ECDF: RMS targets from 10 × to 1.001 × the optimum")


def fig_anytime(anytime: pd.DataFrame, styles: dict) -> Figure | None:
    """Median and inter-quartile band over trials of the best RMS so far relative to the optimum."""
    if anytime.empty:
        return None

    def draw(ax, part, st):
        ax.plot(part["evaluations"], part["median"], color=st["color"], ls=st["ls"], marker=st["marker"],
                markevery=MARK_EVERY, ms=4)
        ax.fill_between(part["evaluations"], part["q25"], part["q75"], color=st["color"], alpha=0.15, lw=0)

    return _scenario_figure(anytime, styles, draw, r"best RMS so far / optimum",
                            "Anytime performance: median over trials, inter-quartile band", log_y=True)


def fig_profile(profile: pd.DataFrame, styles: dict) -> Figure | None:
    """Dolan & Moré performance profile of the expected running time across scenarios."""
    if profile.empty:
        return None
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    fig = Figure(figsize=(7.4, 3.6), layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.subplots()
    confs = _in_order(profile, styles)
    for conf in confs:
        part = profile[profile["configuration"] == conf]
        st = styles[conf]
        ax.step(part["tau"], part["fraction"], where="post", color=st["color"], ls=st["ls"], marker=st["marker"],
                markevery=MARK_EVERY, ms=4)
    log_scale(ax, "x")
    ax.set_ylim(-0.02, 1.02)
    ax.set_xlabel("τ: ERT to 1.01 × optimum, relative to the best method's")
    ax.set_ylabel("fraction of scenarios with ratio ≤ τ")
    ax.set_title("Performance profile (Dolan & Moré) across scenarios")
    _legend(fig, confs, styles)
    return fig


BUILDERS = {"ecdf": fig_ecdf, "anytime": fig_anytime, "profile": fig_profile}

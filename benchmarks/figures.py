"""Figures of a campaign directory, drawn for print: angle errors relative to the Cramér-Rao bound,
accuracy against runtime, convergence over all trials, total field against heading (turntable and
vehicle scenarios only) and efficiency with bootstrap intervals.

    from magbench.benchmarks.figures import make_figures
    make_figures("results/campaign", formats=("png", "pdf"), dpi=300)
    # -> results/campaign/figures/<kind>_<scenario>.png/.pdf

Conventions, the same in every figure: one style (colour, marker, line style) per calibrator
configuration from the campaign's one style map (``benchmarks.styles.campaign_styles``: the campaign's
own configuration order, shared with the comparison figures and the report); the Cramér-Rao bound and the
reference in neutral grey; one scale per figure, logarithmic where values span decades; legends outside
the data and the titles; one set of font sizes (``styles.RC``).

Only the Agg canvas is used (``matplotlib.figure.Figure``, never pyplot), so importing this module does
not change the caller's backend. Output is deterministic: fixed style, fixed SVG hash salt, no dates and
no software tag in the files, a seeded jitter and a seeded bootstrap.
"""
from __future__ import annotations

import gc
import io
import re
import textwrap
import threading
import warnings
from contextlib import contextmanager
from functools import partial
from pathlib import Path

import matplotlib
import numpy as np
import pandas as pd
from matplotlib import style as mpl_style
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.markers import MarkerStyle
from matplotlib.patches import Patch

from magbench.benchmarks import comparison_figures
from magbench.benchmarks.progress import BarSafeStream, progress_bar, slow_phase
from magbench.benchmarks.styles import BOUND_GREY, RC, WARN_COLOUR, campaign_styles, log_scale
from magbench.benchmarks.tables import MIN_TRIALS_EFFICIENCY, efficiency_interval
from magbench.paper import ARCSEC_PER_RAD
from magbench.safeio import atomic_output
from magbench.simulate.scenarios import get_scenario

ANGLES = ("alpha", "beta", "gamma")
GREEK = {"alpha": "α", "beta": "β", "gamma": "γ"}
ANGLE_MARKERS = {"alpha": "o", "beta": "s", "gamma": "^"}
KINDS = ("errors", "accuracy_runtime", "convergence", "field_heading", "efficiency")
"""The per-scenario figure families; ``comparison_figures.COMPARISON_KINDS`` are drawn once per campaign."""
ALL_KINDS = KINDS + comparison_figures.COMPARISON_KINDS
FORMATS = ("png", "svg", "pdf")
DPI = 300  # print resolution of the PNG files
SCREEN_DPI = 100  # the report's embedded images
CONVERGENCE_GRID = 80  # evaluation points of the aggregated convergence curves


# ---------------------------------------------------------------------------------------------- input


def _read_csv(path: Path, str_cols: tuple[str, ...] = ()) -> pd.DataFrame:
    """Read a CSV if it exists and has rows; otherwise an empty frame."""
    if not path.is_file():
        return pd.DataFrame()
    try:
        df = pd.read_csv(path, dtype={c: str for c in str_cols}, keep_default_na=True)
    except (pd.errors.EmptyDataError, pd.errors.ParserError):
        return pd.DataFrame()
    for col in ("scenario", "configuration"):
        if col in df.columns:
            df[col] = df[col].fillna("").astype(str)
            df.loc[df[col] == "", col] = "unknown"
    return df


def _numeric(df: pd.DataFrame, col: str) -> pd.Series:
    """Column as floats (NaN where missing or unparsable); an all-NaN series if the column is absent."""
    if col not in df.columns:
        return pd.Series(np.nan, index=df.index, dtype=float)
    return pd.to_numeric(df[col], errors="coerce").astype(float)


def failed_mask(runs: pd.DataFrame) -> pd.Series:
    """True for runs whose ``error`` text is non-empty."""
    if "error" not in runs.columns:
        return pd.Series(False, index=runs.index)
    return runs["error"].fillna("").astype(str).str.strip() != ""


def _unique(*series: pd.Series) -> list[str]:
    """Distinct values in order of first appearance over several series."""
    seen: dict[str, None] = {}
    for s in series:
        for v in s:
            seen.setdefault(str(v), None)
    return list(seen)


def _col(df: pd.DataFrame, col: str) -> pd.Series:
    return df[col] if col in df.columns else pd.Series([], dtype=object)


def safe_name(scenario: str) -> str:
    """Scenario name made safe for a file name."""
    return re.sub(r"[^A-Za-z0-9._-]+", "_", str(scenario)).strip("_") or "unknown"


def _wrap(label: str, width: int = 26) -> str:
    return "\n".join(textwrap.wrap(str(label), width)) or str(label)


def _trials(df: pd.DataFrame) -> int:
    """Trials per configuration (the most any configuration has)."""
    if df.empty or "configuration" not in df.columns:
        return 0
    return int(df.groupby("configuration").size().max())


# --------------------------------------------------------------------------------------------- output


def _new_figure(width: float, height: float) -> Figure:
    fig = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasAgg(fig)
    return fig


METADATA = {"png": {"Software": None}, "svg": {"Date": None, "Creator": "magbench"},
            "pdf": {"Creator": "magbench", "Producer": None, "CreationDate": None, "ModDate": None}}


def _save(fig: Figure, out_dir: Path, stem: str, formats=("png", "svg"), dpi: int = DPI) -> list[Path]:
    """Write ``stem`` in each format, without dates or software tags."""
    paths = []
    for fmt in formats:
        path = out_dir / f"{stem}.{fmt}"
        with atomic_output(path, force=True) as tmp:  # a link at the name is replaced, not written through
            fig.savefig(tmp, format=fmt, dpi=dpi, metadata=METADATA[fmt])
        paths.append(path)
        freeze_layout(fig)
    return paths


def freeze_layout(fig: Figure) -> None:
    """Keep the layout the first draw solved (in inches, so it holds at every resolution) for the figure's
    later formats and the report's copy: constrained layout re-solved per format was half of the figures'
    time (a tight bounding box of every axis, each time).  No engine at all, not matplotlib's placeholder for one
    ('none'): while any engine is set, ``savefig`` draws the figure once more without rendering before each save,
    a third of the figures' time."""
    with matplotlib.rc_context({"figure.autolayout": False, "figure.constrained_layout.use": False}):
        fig.set_layout_engine(None)


def png_bytes(fig: Figure, dpi: int = SCREEN_DPI) -> bytes:
    """The figure as PNG bytes (for embedding in the report)."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, metadata=METADATA["png"])
    return buf.getvalue()


def _positive(values: np.ndarray) -> np.ndarray:
    values = np.asarray(values, dtype=float)
    return values[np.isfinite(values) & (values > 0)]


def _few_trials_note(fig: Figure, n: int, what: str) -> None:
    """A visible warning in the figure when the trials are too few for what it shows."""
    fig.supxlabel(f"⚠ only {n} trial{'s' if n != 1 else ''}: {what}", color=WARN_COLOUR, fontsize=8)


# -------------------------------------------------------------------------------------------- figures


def _boxplot_h(ax, data: list[np.ndarray], positions: list[float], colour_list: list) -> None:
    """Horizontal box plots, whatever the matplotlib version calls the option."""
    kw = dict(positions=positions, widths=0.55, patch_artist=True, showfliers=False, manage_ticks=False,
              medianprops={"color": "black"})
    try:
        bp = ax.boxplot(data, orientation="horizontal", **kw)
    except TypeError:  # matplotlib < 3.10
        bp = ax.boxplot(data, vert=False, **kw)
    for patch, colour in zip(bp["boxes"], colour_list):
        patch.set_facecolor(colour)
        patch.set_alpha(0.35)


def _relative_errors(ok: pd.DataFrame) -> tuple[dict, bool]:
    """|estimate − truth| per angle, relative to the run's Cramér-Rao standard deviation when every
    angle has one (``True``), else in arc-seconds (``False``)."""
    errs = {a: _numeric(ok, f"{a}_err_rad").abs() for a in ANGLES}
    crbs = {a: _numeric(ok, f"crb_{a}_rad") for a in ANGLES}
    relative = all((crbs[a][errs[a].notna()] > 0).all() and crbs[a][errs[a].notna()].notna().all()
                   for a in ANGLES if errs[a].notna().any())
    if relative:
        return {a: errs[a] / crbs[a] for a in ANGLES}, True
    return {a: errs[a] * ARCSEC_PER_RAD for a in ANGLES}, False


def _log_floor(values: list[np.ndarray]) -> float:
    """Where exact zeros are drawn on a log axis: a decade under the smallest positive value."""
    pos = _positive(np.concatenate(values)) if values else np.array([])
    return float(10.0 ** (np.floor(np.log10(pos.min())) - 1)) if pos.size else 1e-3


def fig_errors(runs: pd.DataFrame, scenario: str, styles: dict) -> Figure | None:
    """|estimate − truth| of α, β, γ per configuration, relative to the Cramér-Rao standard deviation, on
    one logarithmic axis shared by the three panels; the bound (1) and the region under it in grey."""
    ok = runs[~failed_mask(runs)]
    errs, relative = _relative_errors(ok)
    if all(e.isna().all() for e in errs.values()):
        return None
    cfg_col = ok["configuration"] if "configuration" in ok.columns else pd.Series("all", index=ok.index)
    configs = [c for c in _unique(cfg_col) if any(errs[a][cfg_col == c].notna().any() for a in ANGLES)]
    n = len(configs)
    fig = _new_figure(11.0, 1.9 + 0.45 * n)
    axes = fig.subplots(1, 3, sharey=True, sharex=True)
    rng = np.random.default_rng(0)
    every = [e.dropna().to_numpy() for e in errs.values()]
    floor = _log_floor(every)
    for ax, a in zip(axes, ANGLES):
        data, pos, cols = [], [], []
        for i, c in enumerate(configs):
            v = errs[a][cfg_col == c].dropna().to_numpy()
            if v.size:
                data.append(np.maximum(v, floor))
                pos.append(i)
                cols.append(styles[c]["color"])
        if relative:
            ax.axvspan(floor / 10, 1.0, color=BOUND_GREY, alpha=0.12, lw=0, zorder=0)
            ax.axvline(1.0, color=BOUND_GREY, lw=1.2, ls="--", zorder=1)
        if data:
            _boxplot_h(ax, data, pos, cols)  # type: ignore[arg-type]
            for v, p, c in zip(data, pos, [configs[i] for i in pos]):
                marker = styles[c]["marker"]  # a line marker (+, x, 1-4, |, _) is only its edge: it needs a width
                ax.scatter(v, p + rng.uniform(-0.18, 0.18, v.size), s=8, color=styles[c]["color"],
                           marker=marker, alpha=0.75, lw=0 if MarkerStyle(marker).is_filled() else 1.0, zorder=3)
        else:
            ax.text(0.5, 0.5, "no data", transform=ax.transAxes, ha="center", va="center", color="0.4")
        log_scale(ax, "x")
        ax.set_title(f"{GREEK[a]}")
        ax.set_xlabel("|estimate − truth| / Cramér-Rao σ" if relative else "|estimate − truth| (arcsec)")
    hi = max((float(np.max(v)) for v in every if v.size), default=1.0)
    pos = _positive(np.concatenate(every)) if every else np.array([])  # type: ignore[assignment]
    lo = floor / 2 if any((v == 0).any() for v in every) or not pos.size else pos.min() / 2  # type: ignore[attr-defined]
    axes[0].set_xlim(min(lo, 0.5), max(hi, 1.0) * 2)
    axes[0].set_yticks(range(n), [_wrap(c) for c in configs])
    axes[0].set_ylim(n - 0.5, -0.5)
    n_failed = int(failed_mask(runs).sum())
    sigma = ""
    if relative:
        med = {a: np.nanmedian(_numeric(ok, f"crb_{a}_rad")) * ARCSEC_PER_RAD for a in ANGLES}
        sigma = "; Cramér-Rao σ (median): " + ", ".join(f"{GREEK[a]} {med[a]:.3g}″" for a in ANGLES)
    fig.suptitle(_wrap(f"Angle errors{' relative to the Cramér-Rao bound' if relative else ''} — {scenario} "
                       f"({_trials(ok)} trials per method" + (f", {n_failed} failed runs excluded" if n_failed else "")
                       + f"){sigma}", 130))  # wrapped: a long title must not run off the figure
    if relative:
        fig.legend(handles=[Patch(color=BOUND_GREY, alpha=0.25, label="within 1 σ of the Cramér-Rao bound"),
                            Line2D([], [], color=BOUND_GREY, ls="--", label="1 σ (the bound)")],
                   loc="outside lower center", ncols=2)
    return fig


def _median_iqr(v: np.ndarray) -> tuple[float, float, float]:
    q25, q50, q75 = np.percentile(v, [25, 50, 75])
    return float(q50), float(q50 - q25), float(q75 - q50)


def fig_accuracy_runtime(runs: pd.DataFrame, scenario: str, styles: dict) -> Figure | None:
    """Median RMS over the three angles of the error relative to the Cramér-Rao σ against median runtime
    per configuration; bars are inter-quartile ranges."""
    ok = runs[~failed_mask(runs)]
    if "configuration" not in ok.columns:
        return None
    errs, relative = _relative_errors(ok)
    rms = np.sqrt(sum(errs[a] ** 2 for a in ANGLES) / 3.0)
    rt = _numeric(ok, "runtime_s")
    points = []
    for c in _unique(ok["configuration"]):
        sel = ok["configuration"] == c
        r, t = _positive(rms[sel].to_numpy()), _positive(rt[sel].to_numpy())
        if r.size and t.size:
            points.append((c, _median_iqr(t), _median_iqr(r), int(sel.sum())))
    if not points:
        return None
    fig = _new_figure(8.5, 4.8)
    ax = fig.subplots()
    if relative:
        ax.axhline(1.0, color=BOUND_GREY, ls="--", lw=1.2, label="Cramér-Rao bound (1 σ)")
    for c, (tx, tl, th), (ry, rl, rh), n in points:
        ax.errorbar([tx], [ry], xerr=[[tl], [th]], yerr=[[rl], [rh]], fmt=styles[c]["marker"],
                    color=styles[c]["color"], ms=7, capsize=3, lw=1.2, label=f"{_wrap(c, 34)} (n={n})")
    log_scale(ax, "x", "y")
    _direct_labels(ax, [(c, tx, ry, styles[c]["color"]) for c, (tx, _, _), (ry, _, _), _ in points])
    ax.set_xlabel("median runtime per calibration (s)")
    ax.set_ylabel("median RMS angle error / Cramér-Rao σ" if relative else "median RMS angle error (arcsec)")
    ax.set_title(f"Accuracy against runtime — {scenario} (bars: inter-quartile range)")
    fig.legend(loc="outside right upper", title="calibrator")
    return fig


def _direct_labels(ax, points: list[tuple[str, float, float, str]], font_pt: float = 7.5) -> None:
    """Each point's name written beside it (log axes), pushed up or down just enough that no two names
    overlap and no name lies across another's leader: the reader needs no legend lookup where points crowd."""
    ax.autoscale_view()
    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    w_in, h_in = ax.figure.get_size_inches() * np.array([0.62, 0.72])  # the axes' share of the figure, about
    at = [((np.log10(x) - np.log10(x0)) / (np.log10(x1) - np.log10(x0)) * w_in * 72,
           (np.log10(y) - np.log10(y0)) / (np.log10(y1) - np.log10(y0)) * h_in * 72) for _, x, y, _ in points]
    rises = place_labels([(name, px, py) for (name, *_), (px, py) in zip(points, at)], font_pt)
    for (name, x, y, colour), dy in zip(points, rises):
        leader = {"arrowprops": {"arrowstyle": "-", "color": colour, "lw": 0.6, "shrinkA": 0, "shrinkB": 0,
                                 "relpos": (0.0, 0.0)}} \
            if dy > font_pt else {}  # a label pushed away from its point is joined to it by a thin line
        ax.annotate(name, (x, y), xytext=(LABEL_GAP_PT, dy + 3), textcoords="offset points", fontsize=font_pt,
                    color=colour, ha="left", va="bottom", annotation_clip=False, **leader)


LABEL_GAP_PT = 7.0
"""A direct label starts this far right of its point (points)."""


def place_labels(items: list[tuple[str, float, float]], font_pt: float = 7.5) -> list[float]:
    """How far (points) each label of ``items`` (name, x, y in points) rises above its point so that no two
    labels overlap and no label lies across the leader of a label pushed away from its point (a near-vertical
    line from the point to the label's lower-left corner).  Rightmost first: a label pushed up past its
    right-hand neighbours keeps its leader clear of their names.  Returned in the order of ``items``."""
    placed: list[tuple[float, float, float]] = []  # labels: (x, y, width)
    leaders: list[tuple[float, float, float, float]] = []  # (from x, to x, from y, to y)
    rises = [0.0] * len(items)
    for i in sorted(range(len(items)), key=lambda k: (-items[k][1], items[k][2])):
        name, px, py = items[i]
        width = 0.55 * font_pt * len(name)
        left = px + LABEL_GAP_PT
        dy, moved = 0.0, True
        while moved:  # a label pushed past one neighbour may land on another placed before it: check them all again
            moved = False
            for qx, qy, qw in placed:
                if abs(px - qx) < max(width, qw) + 8 and abs(py + dy - qy) < font_pt + 1.99:  # 0.01: rounding
                    dy, moved = qy + font_pt + 2 - py, True
            for xa, xb, lo, hi in leaders:  # a leader rising through this label's box: go above its top
                if xa <= left + width + 1 and xb >= left - 1 and py + dy < hi and py + dy + font_pt > lo:
                    dy, moved = hi + 2 - py, True
        placed.append((px, py + dy, width))
        if dy > font_pt:
            leaders.append((px, px + LABEL_GAP_PT, py, py + dy + 3))
        rises[i] = dy
    return rises


def _segments(part: pd.DataFrame) -> list[pd.DataFrame]:
    """Split a configuration's trace into runs: by ``trial`` if present, else where evaluations restart."""
    if "trial" in part.columns and part["trial"].notna().any():
        return [g for _, g in part.groupby("trial", sort=True)]
    ev = _numeric(part, "evaluations").to_numpy()
    starts = np.flatnonzero(np.r_[True, np.diff(ev) < 0])
    bounds = list(starts) + [len(part)]
    return [part.iloc[bounds[k]:bounds[k + 1]] for k in range(len(starts))]


def convergence_curves(part: pd.DataFrame, grid: np.ndarray) -> np.ndarray:
    """Best F so far of every trial at the evaluation counts ``grid`` (trials x grid; NaN before a run's
    first evaluation; a run that has stopped keeps its final value)."""
    out = []
    for seg in _segments(part):
        ev = _numeric(seg, "evaluations").to_numpy()
        f = _numeric(seg, "best_F").to_numpy()
        keep = np.isfinite(ev) & np.isfinite(f)
        if not keep.any():
            continue
        order = np.argsort(ev[keep], kind="stable")
        ev, f = ev[keep][order], np.minimum.accumulate(f[keep][order])
        idx = np.searchsorted(ev, grid, side="right") - 1
        out.append(np.where(idx >= 0, f[np.clip(idx, 0, None)], np.nan))
    return np.array(out)


def fig_convergence(data: tuple, scenario: str, styles: dict) -> Figure | None:
    """RMS total-field residual √F of the best point so far against objective evaluations: the median over
    all trials (line) and the inter-quartile band; methods that stop after a few evaluations (closed-form
    and Gauss-Newton ones) as a marker with its inter-quartile bar, so that every method is visible.
    ``data`` is (traces, runs): a closed-form method without a trace is placed at one evaluation with the
    final residual of its runs."""
    traces, runs = data
    if traces.empty or "evaluations" not in traces.columns or "configuration" not in traces.columns:
        return None
    ev_all = _positive(_numeric(traces, "evaluations").to_numpy())
    if not ev_all.size or _numeric(traces, "best_F").isna().all():
        return None
    fig = _new_figure(8.5, 4.8)
    ax = fig.subplots()
    handles, n_trials = [], 0
    ok = runs[~failed_mask(runs)] if "configuration" in runs.columns else runs
    for c in [c for c in _unique(_col(ok, "configuration")) if c not in set(traces["configuration"])]:
        rms = _positive(_numeric(ok[ok["configuration"] == c], "rms_after_nT").to_numpy())
        if not rms.size:
            continue
        y, lo, hi = _median_iqr(rms)
        st = styles[c]
        ax.errorbar([1.0], [y], yerr=[[lo], [hi]], fmt=st["marker"], color=st["color"], ms=7, capsize=3, lw=1.2)
        handles.append(Line2D([], [], color=st["color"], marker=st["marker"], ls="none",
                              label=f"{_wrap(c, 30)} ({len(rms)} trials; closed form, final residual)"))
    for c in _unique(traces["configuration"]):
        part = traces[traces["configuration"] == c]
        ev = _positive(_numeric(part, "evaluations").to_numpy())
        if not ev.size:
            continue
        grid = np.unique(np.geomspace(1, ev.max(), CONVERGENCE_GRID).round())
        curves = convergence_curves(part, grid)
        if not curves.size:
            continue
        n_trials = max(n_trials, len(curves))
        rms = np.sqrt(curves)
        st = styles[c]
        label = f"{_wrap(c, 30)} ({len(curves)} trial{'s' if len(curves) != 1 else ''})"
        if ev.max() <= 5:  # a few evaluations: a marker at the median end point
            ends = np.array([[np.nanmax(np.where(np.isfinite(r), grid, np.nan)), r[np.isfinite(r)][-1]]
                             for r in rms if np.isfinite(r).any()])
            x = float(np.median(ends[:, 0]))
            y, lo, hi = _median_iqr(ends[:, 1])
            ax.errorbar([x], [y], yerr=[[lo], [hi]], fmt=st["marker"], color=st["color"], ms=7, capsize=3, lw=1.2)
            handles.append(Line2D([], [], color=st["color"], marker=st["marker"], ls="none", label=label))
            continue
        enough = np.sum(np.isfinite(rms), axis=0) >= max(1, len(rms) / 2)
        with warnings.catch_warnings():  # columns before every run's first evaluation are all NaN
            warnings.simplefilter("ignore", RuntimeWarning)
            q25, q50, q75 = np.nanpercentile(np.where(enough, rms, np.nan), [25, 50, 75], axis=0)
        ax.fill_between(grid[enough], q25[enough], q75[enough], color=st["color"], alpha=0.18, lw=0)
        ax.plot(grid[enough], q50[enough], color=st["color"], ls=st["ls"], lw=1.5)
        handles.append(Line2D([], [], color=st["color"], ls=st["ls"], lw=1.5, label=label))
    if not handles:
        return None
    log_scale(ax, "x", "y")
    ax.set_xlabel("objective evaluations")
    ax.set_ylabel("RMS total-field residual of the best point so far, √F (nT)")
    ax.set_title(f"Convergence — {scenario} (median over trials)")
    handles.append(Patch(color="0.6", alpha=0.3, label="inter-quartile band"))  # type: ignore[arg-type]
    fig.legend(handles=handles, loc="outside right upper", title="calibrator")
    if n_trials < 5:
        _few_trials_note(fig, n_trials, "the median and band rest on very few runs")
    return fig


def _heading_kind(scenario: str, df: pd.DataFrame) -> str | None:
    """``"turntable"``, ``"vehicle"`` or another label when the data have a heading in the sense of a
    rotation about the vertical that sweeps the circle in order; None for random attitudes."""
    try:
        schedule = get_scenario(scenario).schedule
    except Exception:  # an unknown (or user) scenario: judge from the data
        schedule = None
    if schedule in ("turntable", "vehicle"):
        return schedule
    if schedule is not None:
        return None
    first = df[df["configuration"] == df["configuration"].iloc[0]]
    h = np.unwrap(np.radians(first["heading_deg"].to_numpy(float)))
    steps = np.diff(h)
    return "heading" if len(steps) > 3 and (np.mean(steps > 0) > 0.9 or np.mean(steps < 0) > 0.9) else None


def fig_field_heading(fields: pd.DataFrame, scenario: str, styles: dict) -> Figure | None:
    """Total field before/after correction and the reference against heading (trial 0), where the
    scenario has a heading (a turntable or a vehicle turning); none for random attitudes."""
    need = ("heading_deg", "configuration")
    if fields.empty or any(c not in fields.columns for c in need):
        return None
    df = fields.assign(heading_deg=_numeric(fields, "heading_deg"), f_ref_nT=_numeric(fields, "f_ref_nT"),
                       f_before_nT=_numeric(fields, "f_before_nT"), f_after_nT=_numeric(fields, "f_after_nT"))
    df = df[df["heading_deg"].notna()]
    if df.empty or df[["f_ref_nT", "f_before_nT", "f_after_nT"]].isna().all().all():
        return None
    kind = _heading_kind(scenario, df)
    if kind is None:
        return None
    df = df.assign(heading_deg=df["heading_deg"] % 360.0)
    common = df.groupby("heading_deg", sort=True)[["f_ref_nT", "f_before_nT"]].median()
    fig = _new_figure(9.0, 6.0)
    top, bottom = fig.subplots(2, 1, sharex=True, height_ratios=[3, 2])
    h = common.index.to_numpy()
    if np.isfinite(common["f_before_nT"]).any():
        # light grey and wide: no method has it (ga is black), and the corrected curves read on top of it
        top.plot(h, common["f_before_nT"], color="0.7", lw=2.6, label="before (raw readings)")
    if np.isfinite(common["f_ref_nT"]).any():
        top.plot(h, common["f_ref_nT"], color=BOUND_GREY, ls="--", lw=1.2, label="reference")
    for c in _unique(df["configuration"]):
        part = df[df["configuration"] == c].groupby("heading_deg", sort=True)[["f_after_nT", "f_ref_nT"]].median()
        if part["f_after_nT"].notna().any():
            st = styles[c]
            top.plot(part.index, part["f_after_nT"], color=st["color"], ls=st["ls"], lw=1.1,
                     label=f"after: {_wrap(c, 34)}")
            bottom.plot(part.index, part["f_after_nT"] - part["f_ref_nT"], color=st["color"], ls=st["ls"], lw=1.1)
    bottom.axhline(0.0, color=BOUND_GREY, ls="--", lw=1.0)
    top.set_ylabel("total field (nT)")
    bottom.set_ylabel("after − reference (nT)")
    bottom.set_xlabel({"turntable": "turntable heading (deg)", "vehicle": "vehicle heading, yaw (deg)"}
                      .get(kind, "heading (deg)"))
    bottom.set_xticks(np.arange(0, 361, 45))
    bottom.set_xlim(0, 360)
    top.set_title(f"Total field against heading — {scenario} (trial 0)")
    top.ticklabel_format(axis="y", useOffset=False, style="plain")
    fig.legend(*top.get_legend_handles_labels(), loc="outside right upper")
    return fig


def efficiency_table(runs: pd.DataFrame) -> pd.DataFrame:
    """Efficiency (CRB variance / MSE) per configuration and angle with its 95 % bootstrap interval and
    the number of successful trials behind it."""
    ok = runs[~failed_mask(runs)]
    if "success" in ok.columns:
        ok = ok[ok["success"].astype("boolean").fillna(False).astype(bool)]
    rows = []
    for c in _unique(_col(ok, "configuration")):
        part = ok[ok["configuration"] == c]
        for a in ANGLES:
            err, crb = _numeric(part, f"{a}_err_rad").to_numpy(), _numeric(part, f"crb_{a}_rad").to_numpy()
            keep = np.isfinite(err) & np.isfinite(crb)
            if keep.sum() < 2:
                continue
            with np.errstate(divide="ignore"):
                value = float(np.mean(crb[keep] ** 2) / np.mean(err[keep] ** 2))
            lo, hi = efficiency_interval(err[keep], crb[keep])
            rows.append({"configuration": c, "angle": a, "efficiency": value, "lo": lo, "hi": hi, "n": int(keep.sum())})
    return pd.DataFrame(rows)


def fig_efficiency(runs: pd.DataFrame, scenario: str, styles: dict) -> Figure | None:
    """Efficiency (CRB variance / MSE) of α, β, γ per configuration with 95 % bootstrap intervals, on a
    log axis; 1 (grey) is the bound.  Warns in the figure below ``MIN_TRIALS_EFFICIENCY`` trials."""
    eff = efficiency_table(runs)
    if eff.empty:
        return None
    eff = eff[np.isfinite(eff["efficiency"]) & (eff["efficiency"] > 0)]
    if eff.empty:
        return None
    configs = _unique(eff["configuration"])
    n = len(configs)
    fig = _new_figure(max(6.5, 0.9 * n + 3.5), 4.8)
    ax = fig.subplots()
    ax.axhline(1.0, color=BOUND_GREY, ls="--", lw=1.2)
    offsets = {"alpha": -0.22, "beta": 0.0, "gamma": 0.22}
    for i, c in enumerate(configs):
        for _, r in eff[eff["configuration"] == c].iterrows():
            x = i + offsets[r["angle"]]
            y = r["efficiency"]
            lo = y - r["lo"] if np.isfinite(r["lo"]) else 0.0
            hi = r["hi"] - y if np.isfinite(r["hi"]) else 0.0
            ax.errorbar([x], [y], yerr=[[max(lo, 0.0)], [max(hi, 0.0)]], fmt=ANGLE_MARKERS[r["angle"]],
                        color=styles[c]["color"], mec="black", mew=0.5, ms=6, capsize=2.5, lw=1.1)
    log_scale(ax, "y")
    vals = _positive(np.r_[eff["lo"].to_numpy(float), eff["hi"].to_numpy(float), eff["efficiency"].to_numpy(float)])
    ax.set_ylim(min(vals.min(), 0.5) / 2, max(vals.max(), 2.0) * 2)
    ax.set_xticks(range(n), [_wrap(c, 18) for c in configs], rotation=25 if n > 6 else 0,
                  ha="right" if n > 6 else "center", rotation_mode="anchor")
    ax.set_xlim(-0.6, n - 0.4)
    ax.set_ylabel("efficiency = Cramér-Rao variance / MSE")
    n_min = int(eff["n"].min())
    n_max = int(eff["n"].max())
    ax.set_title(f"Efficiency against the Cramér-Rao bound — {scenario} "
                 f"({n_min if n_min == n_max else f'{n_min}-{n_max}'} trials)")
    handles = [Line2D([], [], color="0.3", marker=ANGLE_MARKERS[a], ls="none", label=GREEK[a]) for a in ANGLES]
    handles.append(Line2D([], [], color="0.3", marker="|", ms=12, ls="none", label="95 % bootstrap interval"))
    handles.append(Line2D([], [], color=BOUND_GREY, ls="--", label="the bound (efficiency 1)"))
    fig.legend(handles=handles, loc="outside right upper")
    if n_min < MIN_TRIALS_EFFICIENCY:
        _few_trials_note(fig, n_min, f"an efficiency needs about {MIN_TRIALS_EFFICIENCY} or more to be "
                         "quoted; read the intervals, not the points")
    return fig


BUILDERS = (("errors", fig_errors, "runs"), ("accuracy_runtime", fig_accuracy_runtime, "runs"),
            ("convergence", fig_convergence, "traces"), ("field_heading", fig_field_heading, "fields"),
            ("efficiency", fig_efficiency, "runs"))
BUILDER_OF = {kind: build for kind, build, _ in BUILDERS}


# ------------------------------------------------------------------------------------------------ API


def figure_tasks(campaign_dir: Path, kinds=ALL_KINDS) -> list[tuple[str, str | None, object]]:
    """Every figure the campaign's files support, as ``(kind, scenario or None, data)``: the per-scenario
    families from runs.csv, traces.csv and fields.csv, then the comparison's from comparison/*.csv."""
    frames = {"runs": _read_csv(campaign_dir / "runs.csv", str_cols=("error", "configuration", "scenario")),
              "traces": _read_csv(campaign_dir / "traces.csv", str_cols=("configuration", "scenario")),
              "fields": _read_csv(campaign_dir / "fields.csv", str_cols=("configuration", "scenario"))}
    scenarios = _unique(*(_col(f, "scenario") for f in frames.values()))

    def of(df: pd.DataFrame, scenario: str) -> pd.DataFrame:
        return df[df["scenario"] == scenario] if "scenario" in df.columns else df.iloc[0:0]

    tasks: list[tuple[str, str | None, object]] = []
    for scenario in scenarios:
        for kind, _, key in BUILDERS:
            data = of(frames[key], scenario)
            if kind not in kinds or data.empty:
                continue
            tasks.append((kind, scenario, (data, of(frames["runs"], scenario)) if kind == "convergence" else data))
    for kind in comparison_figures.COMPARISON_KINDS:
        table = _read_csv(campaign_dir / "comparison" / f"{kind}.csv", str_cols=("configuration", "scenario"))
        if kind in kinds and not table.empty and "configuration" in table.columns:
            tasks.append((kind, None, table))
    return tasks


def figure_stem(kind: str, scenario: str | None) -> str:
    """The file stem of a figure: ``<kind>_<scenario>`` per scenario, ``<kind>`` for a campaign-wide one."""
    return kind if scenario is None else f"{kind}_{safe_name(scenario)}"


def _draw(task: tuple, styles: dict, out_dir: Path, formats: tuple, dpi: int, screen: bool
          ) -> tuple[str, list[Path], bytes | None]:
    """Draw one figure task and write it in every format (and its screen copy): (stem, paths, PNG bytes)."""
    kind, scenario, data = task
    with matplotlib.rc_context():
        mpl_style.use("default")
        matplotlib.rcParams.update(RC)  # type: ignore[arg-type]
        build = comparison_figures.BUILDERS[kind] if scenario is None else partial(BUILDER_OF[kind], scenario=scenario)
        fig = build(data, styles=styles)
        if fig is None:
            return figure_stem(kind, scenario), [], None
        stem = figure_stem(kind, scenario)
        paths = _save(fig, out_dir, stem, formats, dpi) if formats else []
        return stem, paths, png_bytes(fig) if screen else None


def _draw_star(args: tuple) -> tuple[str, list[Path], bytes | None]:
    return _draw(*args)


@contextmanager
def _pool(jobs: int):
    """A process pool of ``jobs`` workers, forked where the platform can (the parent has matplotlib and
    pandas loaded already: a forked worker starts in milliseconds, a spawned one re-imports them).  While it
    lives this process's objects are frozen out of the collector's sight (``gc.freeze``): the workers'
    collections then do not walk the inherited objects, whose pages stay shared instead of being copied
    (7 % of the drawing's time)."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    methods = multiprocessing.get_all_start_methods()
    context = multiprocessing.get_context("fork" if "fork" in methods else None)
    gc.freeze()
    try:
        with ProcessPoolExecutor(max_workers=jobs, mp_context=context) as pool:
            yield pool
    finally:
        gc.unfreeze()


def make_figures(campaign_dir: str | Path, out_dir: str | Path | None = None, formats=("png", "svg"),
                 dpi: int = DPI, images: dict | None = None, progress: bool = False, jobs: int = 1,
                 kinds=ALL_KINDS, prepare=None) -> list[Path]:
    """Draw every figure the campaign's data support (``kinds``: the per-scenario families and the method
    comparison's ECDF, anytime and profile figures) in each of ``formats`` (png, svg, pdf; PNG at ``dpi``);
    return the written paths.  ``images``, when given, receives ``{stem: PNG bytes}`` at screen resolution
    for the report (``formats=()`` then writes nothing).  ``jobs`` > 1 draws on that many processes; the
    files are the same either way.  ``prepare``, when given, is called in this process once the
    per-scenario figures are under way (the method comparison's tables: their figures are drawn after it),
    so that it overlaps the drawing.  ``progress`` shows progress on stderr."""
    bad = [f for f in formats if f not in FORMATS]
    if bad:
        raise ValueError(f"unknown figure format {bad[0]!r}; known: {', '.join(FORMATS)}")
    campaign_dir = Path(campaign_dir)
    out_dir = Path(out_dir) if out_dir is not None else campaign_dir / "figures"
    first = [k for k in kinds if k in KINDS]
    later = [k for k in kinds if k not in KINDS]
    tasks = figure_tasks(campaign_dir, first)
    runs = _read_csv(campaign_dir / "runs.csv", str_cols=("error", "configuration", "scenario"))
    styles = campaign_styles(campaign_dir, _col(runs, "configuration"))
    if formats:
        out_dir.mkdir(parents=True, exist_ok=True)

    def args_of(batch):
        return [(t, styles, out_dir, tuple(formats), dpi, images is not None) for t in batch]

    done: list[tuple[str, list[Path], bytes | None]] = []
    with progress_bar(len(tasks) + len(later), "figures", "fig", enabled=progress) as bar:
        lock = threading.Lock()

        def one_more(_future=None) -> None:  # a figure drawn: counted as it ends, not when collected
            with lock:
                bar.update(1)

        def prepared() -> None:  # the comparison's tables can take a minute: said so, not silent
            with slow_phase("the method comparison's tables (expected running times, ECDFs, paired tests)",
                            enabled=progress, stream=BarSafeStream(bar)):
                prepare()

        if jobs > 1:
            with _pool(jobs) as pool:
                futures = [pool.submit(_draw_star, a) for a in args_of(tasks)]
                for fut in futures:
                    fut.add_done_callback(one_more)
                if prepare is not None:
                    prepared()
                futures += [pool.submit(_draw_star, a) for a in args_of(figure_tasks(campaign_dir, later))]
                for fut in futures[len(tasks):]:
                    fut.add_done_callback(one_more)
                for fut in futures:
                    done.append(fut.result())
        else:
            if prepare is not None:
                prepared()
            for a in args_of(tasks + figure_tasks(campaign_dir, later)):
                done.append(_draw_star(a))
                one_more()
    written: list[Path] = []
    for stem, paths, png in done:
        written += paths
        if images is not None and png is not None:
            images[stem] = png
    return written

"""Figures of a campaign directory: angle errors, accuracy against runtime, convergence, total field
against heading and efficiency against the Cramér-Rao bound, each as PNG (dpi 120) and SVG.

    from magbench.benchmarks.figures import make_figures
    make_figures("results/campaign")          # -> results/campaign/figures/<kind>_<scenario>.png/.svg

Only the Agg canvas is used (``matplotlib.figure.Figure``, never pyplot), so importing this module does
not change the caller's backend. Output is deterministic: fixed style, fixed SVG hash salt, no dates and
no software tag in the files, a seeded jitter.
"""
from __future__ import annotations

import re
import textwrap
from pathlib import Path

import matplotlib
import numpy as np
import pandas as pd
from matplotlib import style as mpl_style
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from magbench.paper import ARCSEC_PER_RAD

ANGLES = ("alpha", "beta", "gamma")
GREEK = {"alpha": "α", "beta": "β", "gamma": "γ"}
KINDS = ("errors", "accuracy_runtime", "convergence", "field_heading", "efficiency")
DPI = 120
SVG_SALT = "magbench"
MARKERS = ("o", "s", "D", "^", "v", "P", "X", "<", ">", "*", "h", "p")
RC = {"svg.hashsalt": SVG_SALT, "svg.fonttype": "path", "figure.dpi": 100, "savefig.dpi": DPI,
      "axes.grid": True, "grid.alpha": 0.3, "font.size": 9, "legend.fontsize": 8, "axes.titlesize": 10}


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


# --------------------------------------------------------------------------------------------- output


def _new_figure(width: float, height: float) -> Figure:
    fig = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _save(fig: Figure, out_dir: Path, stem: str) -> list[Path]:
    """Write ``stem``.png and ``stem``.svg without dates or software tags."""
    png, svg = out_dir / f"{stem}.png", out_dir / f"{stem}.svg"
    fig.savefig(png, format="png", dpi=DPI, metadata={"Software": None})
    fig.savefig(svg, format="svg", metadata={"Date": None, "Creator": "magbench"})
    return [png, svg]


def _colours(configs: list[str]) -> dict[str, tuple]:
    cmap = matplotlib.colormaps["tab10" if len(configs) <= 10 else "tab20"]
    return {c: cmap(i % cmap.N) for i, c in enumerate(configs)}


def _positive(values: np.ndarray) -> np.ndarray:
    values = np.asarray(values, dtype=float)
    return values[np.isfinite(values) & (values > 0)]


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


def fig_errors(runs: pd.DataFrame, scenario: str, colours: dict) -> Figure | None:
    """Signed alpha/beta/gamma errors per configuration in arcsec, with the CRB ±1σ band."""
    ok = runs[~failed_mask(runs)]
    errs = {a: _numeric(ok, f"{a}_err_rad") * ARCSEC_PER_RAD for a in ANGLES}
    crbs = {a: _numeric(ok, f"crb_{a}_rad") * ARCSEC_PER_RAD for a in ANGLES}
    if all(e.isna().all() for e in errs.values()):
        return None
    cfg_col = ok["configuration"] if "configuration" in ok.columns else pd.Series("all", index=ok.index)
    configs = [c for c in _unique(cfg_col) if any(errs[a][cfg_col == c].notna().any() for a in ANGLES)]
    n = len(configs)
    fig = _new_figure(11.0, 1.6 + 0.5 * n)
    axes = fig.subplots(1, 3, sharey=True)
    rng = np.random.default_rng(0)
    band_drawn = False
    for ax, a in zip(axes, ANGLES):
        data, pos, cols = [], [], []
        for i, c in enumerate(configs):
            v = errs[a][cfg_col == c].dropna().to_numpy()
            if v.size:
                data.append(v)
                pos.append(i)
                cols.append(colours[c])
            s = np.nanmedian(crbs[a][cfg_col == c].to_numpy()) if crbs[a][cfg_col == c].notna().any() else np.nan
            if np.isfinite(s) and s > 0:
                ax.fill_betweenx([i - 0.4, i + 0.4], -s, s, color="tab:green", alpha=0.25, lw=0, zorder=0)
                band_drawn = True
        ax.axvline(0.0, color="grey", lw=0.8, zorder=1)
        if data:
            _boxplot_h(ax, data, pos, cols)
            for v, p, col in zip(data, pos, cols):
                ax.scatter(v, p + rng.uniform(-0.18, 0.18, v.size), s=7, color=col, alpha=0.7, lw=0, zorder=3)
            allv = np.abs(np.concatenate(data))
            nz = _positive(allv)
            if nz.size and nz.max() > 1e3 * np.median(nz):
                ax.set_xscale("symlog", linthresh=float(10.0 ** np.floor(np.log10(np.percentile(nz, 5)))),
                              linscale=1.0)
        else:
            ax.text(0.5, 0.5, "no data", transform=ax.transAxes, ha="center", va="center", color="0.4")
            ax.set_xticks([])
        ax.set_title(f"{GREEK[a]} error")
        ax.set_xlabel("estimate − truth (arcsec)")
    axes[0].set_yticks(range(n), [_wrap(c) for c in configs])
    axes[0].set_ylim(n - 0.5, -0.5)
    n_failed = int(failed_mask(runs).sum())
    fig.suptitle(f"Angle recovery errors — {scenario} ({len(ok)} runs"
                 + (f", {n_failed} failed run{'s' if n_failed != 1 else ''} excluded)" if n_failed else ")"))
    if band_drawn:
        fig.legend(handles=[Patch(color="tab:green", alpha=0.25, label="CRB ±1σ (median over trials)")],
                   loc="outside lower center")
    return fig


def _median_iqr(v: np.ndarray) -> tuple[float, float, float]:
    q25, q50, q75 = np.percentile(v, [25, 50, 75])
    return float(q50), float(q50 - q25), float(q75 - q50)


def fig_accuracy_runtime(runs: pd.DataFrame, scenario: str, colours: dict) -> Figure | None:
    """Median RMS angle error against median runtime per configuration, IQR as error bars."""
    ok = runs[~failed_mask(runs)]
    if "configuration" not in ok.columns:
        return None
    rms = np.sqrt(sum(_numeric(ok, f"{a}_err_rad") ** 2 for a in ANGLES) / 3.0) * ARCSEC_PER_RAD
    rt = _numeric(ok, "runtime_s")
    points = []
    for i, c in enumerate(_unique(ok["configuration"])):
        sel = ok["configuration"] == c
        r, t = _positive(rms[sel].to_numpy()), _positive(rt[sel].to_numpy())
        if r.size and t.size:
            points.append((i, c, _median_iqr(t), _median_iqr(r), int(sel.sum())))
    if not points:
        return None
    fig = _new_figure(8.5, 4.8)
    ax = fig.subplots()
    for i, c, (tx, tl, th), (ry, rl, rh), n in points:
        ax.errorbar([tx], [ry], xerr=[[tl], [th]], yerr=[[rl], [rh]], fmt=MARKERS[i % len(MARKERS)],
                    color=colours[c], ms=7, capsize=3, lw=1.2, label=f"{_wrap(c, 34)} (n={n})")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("median runtime (s)")
    ax.set_ylabel("median RMS angle error √((α²+β²+γ²)/3) (arcsec)")
    ax.set_title(f"Accuracy against runtime — {scenario} (bars: inter-quartile range)")
    fig.legend(loc="outside right upper", title="configuration")
    return fig


def _segments(part: pd.DataFrame) -> list[pd.DataFrame]:
    """Split a configuration's trace into runs: by ``trial`` if present, else where evaluations restart."""
    if "trial" in part.columns and part["trial"].notna().any():
        return [g for _, g in part.groupby("trial", sort=True)]
    ev = _numeric(part, "evaluations").to_numpy()
    starts = np.flatnonzero(np.r_[True, np.diff(ev) < 0])
    bounds = list(starts) + [len(part)]
    return [part.iloc[bounds[k]:bounds[k + 1]] for k in range(len(starts))]


def fig_convergence(traces: pd.DataFrame, scenario: str, colours: dict) -> Figure | None:
    """best_F (solid) and mean_F (dashed) against cumulative evaluations, log-log."""
    if traces.empty or "evaluations" not in traces.columns or "configuration" not in traces.columns:
        return None
    if _numeric(traces, "best_F").isna().all() and _numeric(traces, "mean_F").isna().all():
        return None
    fig = _new_figure(8.5, 4.8)
    ax = fig.subplots()
    handles, drew_mean, drew_any = [], False, False
    for c in _unique(traces["configuration"]):
        part = traces[traces["configuration"] == c]
        drew_cfg = False
        for seg in _segments(part):
            ev = _numeric(seg, "evaluations").to_numpy()
            for col, style in (("best_F", "-"), ("mean_F", "--")):
                y = _numeric(seg, col).to_numpy()
                keep = np.isfinite(ev) & (ev > 0) & np.isfinite(y) & (y > 0)
                if keep.sum() == 0:
                    continue
                order = np.argsort(ev[keep], kind="stable")
                ax.plot(ev[keep][order], y[keep][order], style, color=colours[c], lw=1.2 if style == "-" else 0.9,
                        alpha=0.85, marker="." if keep.sum() == 1 else None)
                drew_cfg = True
                drew_mean |= col == "mean_F"
        if drew_cfg:
            handles.append(Line2D([], [], color=colours[c], lw=1.5, label=_wrap(c, 34)))
            drew_any = True
    if not drew_any:
        return None
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("objective evaluations (cumulative)")
    ax.set_ylabel("F, mean squared total-field error (nT²)")
    ax.set_title(f"Convergence — {scenario}")
    handles.append(Line2D([], [], color="black", ls="-", label="best F"))
    if drew_mean:
        handles.append(Line2D([], [], color="black", ls="--", label="mean F of the batch"))
    fig.legend(handles=handles, loc="outside right upper")
    return fig


def fig_field_heading(fields: pd.DataFrame, scenario: str, colours: dict) -> Figure | None:
    """Total field before/after correction and the reference against turntable heading."""
    need = ("heading_deg", "configuration")
    if fields.empty or any(c not in fields.columns for c in need):
        return None
    df = fields.assign(heading_deg=_numeric(fields, "heading_deg"), f_ref_nT=_numeric(fields, "f_ref_nT"),
                       f_before_nT=_numeric(fields, "f_before_nT"), f_after_nT=_numeric(fields, "f_after_nT"))
    df = df[df["heading_deg"].notna()]
    if df.empty or df[["f_ref_nT", "f_before_nT", "f_after_nT"]].isna().all().all():
        return None
    common = df.groupby("heading_deg", sort=True)[["f_ref_nT", "f_before_nT"]].median()
    fig = _new_figure(9.0, 6.0)
    top, bottom = fig.subplots(2, 1, sharex=True, height_ratios=[3, 2])
    h = common.index.to_numpy()
    ref = common["f_ref_nT"].to_numpy()
    if np.isfinite(common["f_before_nT"]).any():
        top.plot(h, common["f_before_nT"], color="0.45", lw=1.8, marker=".", label="before (raw readings)")
    if np.isfinite(ref).any():
        top.plot(h, ref, color="black", ls="--", lw=1.2, label="reference")
    for c in _unique(df["configuration"]):
        part = df[df["configuration"] == c].groupby("heading_deg", sort=True)[["f_after_nT", "f_ref_nT"]].median()
        if part["f_after_nT"].notna().any():
            top.plot(part.index, part["f_after_nT"], color=colours[c], lw=1.1, label=f"after: {_wrap(c, 34)}")
            bottom.plot(part.index, part["f_after_nT"] - part["f_ref_nT"], color=colours[c], lw=1.1, marker=".",
                        ms=3)
    bottom.axhline(0.0, color="black", ls="--", lw=1.0)
    top.set_ylabel("total field (nT)")
    bottom.set_ylabel("after − reference (nT)")
    bottom.set_xlabel("turntable heading (deg)")
    if h.size and np.nanmax(h) - np.nanmin(h) > 90:
        bottom.set_xticks(np.arange(45 * np.floor(np.nanmin(h) / 45), np.nanmax(h) + 1, 45))
    top.set_title(f"Total field against heading — {scenario}")
    top.ticklabel_format(axis="y", useOffset=False, style="plain")
    fig.legend(*top.get_legend_handles_labels(), loc="outside right upper")
    return fig


def fig_efficiency(summary: pd.DataFrame, scenario: str, colours: dict) -> Figure | None:
    """Efficiency (CRB variance / MSE) of alpha, beta, gamma per configuration; 1 means efficient."""
    cols = [f"efficiency_{a}" for a in ANGLES]
    if summary.empty or "configuration" not in summary.columns or not any(c in summary.columns for c in cols):
        return None
    eff = pd.DataFrame({a: _numeric(summary, f"efficiency_{a}") for a in ANGLES})
    eff.index = summary["configuration"].to_numpy()
    eff = eff[eff.notna().any(axis=1)]
    eff = eff[~eff.index.duplicated()]
    if eff.empty:
        return None
    pos = _positive(eff.to_numpy().ravel())
    log = pos.size > 0 and max(pos.max(), 1.0) / min(pos.min(), 1.0) > 30
    n = len(eff)
    fig = _new_figure(max(6.5, 1.2 * n + 3.0), 4.8)
    ax = fig.subplots()
    x = np.arange(n)
    width = 0.26
    hatch_colour = {"alpha": "tab:blue", "beta": "tab:orange", "gamma": "tab:green"}
    for k, a in enumerate(ANGLES):
        v = eff[a].to_numpy(dtype=float)
        keep = np.isfinite(v) & ((v > 0) if log else np.ones_like(v, dtype=bool))
        ax.bar(x[keep] + (k - 1) * width, v[keep], width, color=hatch_colour[a], label=GREEK[a], log=log)
        for xi in x[~keep]:
            ax.text(xi + (k - 1) * width, 1.0 if log else 0.0, "n/a", rotation=90, ha="center", va="bottom",
                    fontsize=7, color="0.4")
    ax.axhline(1.0, color="black", ls="--", lw=1.0, label="bound (efficiency 1)")
    if log:
        lo, hi = min(pos.min(), 1.0), max(pos.max(), 1.0)
        ax.set_ylim(lo / 2.0, hi * 2.0)
    else:
        ax.set_ylim(0.0, max(float(np.nanmax(eff.to_numpy())) if pos.size else 1.0, 1.0) * 1.15)
    ax.set_xticks(x, [_wrap(c, 18) for c in eff.index], rotation=25, ha="right", rotation_mode="anchor")
    ax.set_ylabel("efficiency = CRB variance / MSE")
    ax.set_title(f"Efficiency against the Cramér-Rao bound — {scenario}")
    fig.legend(loc="outside right upper")
    return fig


# ------------------------------------------------------------------------------------------------ API


def make_figures(campaign_dir: str | Path, out_dir: str | Path | None = None) -> list[Path]:
    """Draw every figure the campaign's data support; return the written PNG and SVG paths."""
    campaign_dir = Path(campaign_dir)
    out_dir = Path(out_dir) if out_dir is not None else campaign_dir / "figures"
    runs = _read_csv(campaign_dir / "runs.csv", str_cols=("error", "configuration", "scenario"))
    summary = _read_csv(campaign_dir / "summary.csv", str_cols=("configuration", "scenario"))
    traces = _read_csv(campaign_dir / "traces.csv", str_cols=("configuration", "scenario"))
    fields = _read_csv(campaign_dir / "fields.csv", str_cols=("configuration", "scenario"))
    frames = (runs, summary, traces, fields)
    scenarios = _unique(*(_col(f, "scenario") for f in frames))
    colours = _colours(_unique(*(_col(f, "configuration") for f in frames)))

    def of(df: pd.DataFrame, scenario: str) -> pd.DataFrame:
        return df[df["scenario"] == scenario] if "scenario" in df.columns else df.iloc[0:0]

    written: list[Path] = []
    with matplotlib.rc_context():
        mpl_style.use("default")
        matplotlib.rcParams.update(RC)
        for scenario in scenarios:
            r, s, t, f = (of(df, scenario) for df in frames)
            builders = (("errors", fig_errors, r), ("accuracy_runtime", fig_accuracy_runtime, r),
                        ("convergence", fig_convergence, t), ("field_heading", fig_field_heading, f),
                        ("efficiency", fig_efficiency, s))
            for kind, build, data in builders:
                if data.empty:
                    continue
                fig = build(data, scenario, colours)
                if fig is None:
                    continue
                out_dir.mkdir(parents=True, exist_ok=True)
                written += _save(fig, out_dir, f"{kind}_{safe_name(scenario)}")
    return written

"""Every figure of the harness (matplotlib, drawn off screen), and the one way to save one.

Callers pass data (data frames or arrays) and a base path; each function draws, saves the
figure as ``base.png`` and ``base.pdf`` with :func:`save_figure` and returns both paths
(``None`` where there is nothing to draw).  This is the only module of ``benchmarks/`` that
imports matplotlib.

* :func:`observer_bounds` -- one observer's interval bounds over time with the true state,
  one panel per state (the figures linked from ``report.md``);
* :func:`bounds_over_time` -- the bounds of the tightest observers for one state (HTML report);
* :func:`heat_map` -- relative RMS radius, observer x state (HTML report);
* :func:`step_times` -- per-step times on a log scale beside the papers' (HTML report);
* :func:`history` -- the golden summaries over the commits (``setobs-bench history``);
* :func:`scaling` -- step + hull time against the number of states (scaling study);
* :func:`datadriven` -- bounds and sets of the data-driven study (Alanwar et al. 2022).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from observers.registry import table_order  # noqa: E402

from ..io import atomic_write_with  # noqa: E402

#: resolution of the PNG files (dots per inch)
DPI = 100
#: panels of :func:`observer_bounds` (the first states)
MAX_FIGURE_STATES = 6
#: observers drawn by :func:`bounds_over_time` (the tightest ones)
BOUNDS_OBSERVERS = 4


def save_figure(fig, base: str | Path, dpi: int = DPI) -> list[Path]:
    """Save ``fig`` as ``base.png`` and ``base.pdf`` (each atomically), close it and return
    both paths."""
    base = Path(base)
    paths = [base.parent / (base.name + ".png"), base.parent / (base.name + ".pdf")]
    try:
        for path in paths:
            atomic_write_with(path, lambda tmp: fig.savefig(tmp, dpi=dpi))
    finally:
        plt.close(fig)
    return paths


def observer_bounds(runs: pd.DataFrame, scenario: str, observer: str,
                    state_names: Sequence[str], base: Path) -> list[Path] | None:
    """Interval bounds of ``observer`` over time with the true state, one panel per state
    (the first :data:`MAX_FIGURE_STATES`); violating steps marked."""
    g = runs[(runs["scenario"] == scenario) & (runs["observer"] == observer)]
    if g.empty or not np.isfinite(g["lo"]).any():
        return None
    n = int(g["state"].max()) + 1
    k = min(n, MAX_FIGURE_STATES)
    fig, axes = plt.subplots(k, 1, figsize=(7, 1.6 * k + 0.6), sharex=True, squeeze=False)
    for i, ax in enumerate(axes[:, 0]):
        s = g[g["state"] == i]
        ax.fill_between(s["t"], s["lo"], s["hi"], color="tab:blue", alpha=0.3, lw=0,
                        label="estimated interval")
        if np.isfinite(s["x_true"]).any():
            ax.plot(s["t"], s["x_true"], color="k", lw=0.8, label="true state")
            bad = s[s["contained"] == 0]
            if len(bad):
                ax.plot(bad["t"], bad["x_true"], "rx", ms=4, label="outside")
        ax.set_ylabel(state_names[i] if i < len(state_names) else f"x{i + 1}", fontsize=8)
        ax.tick_params(labelsize=7)
    axes[0, 0].set_title(f"{observer} on {scenario}", fontsize=9)
    axes[0, 0].legend(fontsize=7, loc="upper right")
    axes[-1, 0].set_xlabel("t [s]", fontsize=8)
    fig.tight_layout()
    return save_figure(fig, base, dpi=90)


def bounds_over_time(runs: pd.DataFrame, summary: pd.DataFrame, scenario: str, state: int,
                     base: Path, label: str) -> list[Path] | None:
    """The lower and upper bounds of the tightest observers (at most
    :data:`BOUNDS_OBSERVERS`, by the RMS radius of ``state``) over time, with the true state,
    like the papers' figures."""
    ok = summary[(summary["scenario"] == scenario) & (summary["state"] == state)
                 & (summary["status"] == "ok") & summary["rms_radius"].notna()]
    best = ok.sort_values("rms_radius")["observer"].head(BOUNDS_OBSERVERS).tolist()
    g = runs[(runs["scenario"] == scenario) & (runs["state"] == state)]
    if not best or g.empty:
        return None
    fig, ax = plt.subplots(figsize=(7, 3.2))
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for obs, color in zip(best, colors, strict=False):
        s = g[g["observer"] == obs]
        ax.plot(s["t"], s["lo"], color=color, lw=1, label=obs)
        ax.plot(s["t"], s["hi"], color=color, lw=1)
    s = g[g["observer"] == best[0]]
    if np.isfinite(s["x_true"]).any():
        ax.plot(s["t"], s["x_true"], color="k", lw=1.2, ls="--", label="true state")
    ax.set_xlabel("t [s]")
    ax.set_ylabel(label)
    ax.set_title(f"{scenario}: bounds of {label} (the {len(best)} tightest observers)",
                 fontsize=9)
    ax.legend(fontsize=7, ncol=3)
    fig.tight_layout()
    return save_figure(fig, base)


def heat_map(df: pd.DataFrame, scenario: str, base: Path) -> list[Path] | None:
    """Relative RMS (eq. 9, ``rel_rms``) as a heat map, observer x state, log colour scale."""
    ok = df[(df["status"] == "ok") & df["rel_rms"].notna()]
    if ok.empty:
        return None
    mat = ok.pivot_table(index="observer", columns="state", values="rel_rms")
    mat = mat.reindex(table_order(mat.index))
    vals = mat.to_numpy(float)
    n_obs, n = vals.shape
    fig, ax = plt.subplots(figsize=(min(2.5 + 0.5 * n, 12), 1.2 + 0.2 * n_obs))
    im = ax.imshow(np.log10(vals), cmap="viridis_r", aspect="auto")
    ax.set_yticks(range(n_obs), mat.index, fontsize=7)
    ax.set_xticks(range(n), [f"x{i + 1}" for i in mat.columns], fontsize=7)
    if n <= 10:
        for (i, j), v in np.ndenumerate(vals):
            if np.isfinite(v):
                ax.text(j, i, f"{v:.3g}", ha="center", va="center", fontsize=6,
                        color="w" if np.log10(v) > np.nanmean(np.log10(vals)) else "k")
    cb = fig.colorbar(im, ax=ax)
    cb.set_label("log10 relative RMS", fontsize=7)
    ax.set_title(f"{scenario}: relative RMS radius (1 = tightest)", fontsize=9)
    fig.tight_layout()
    return save_figure(fig, base)


def step_times(observers: Sequence[str], ours: np.ndarray, theirs: np.ndarray, scenario: str,
               parallel: bool, base: Path) -> list[Path] | None:
    """Per-step time (median ms, log scale) of every observer, beside the paper's time
    (``theirs``: NaN where the paper has none)."""
    if not np.isfinite(ours).any():
        return None
    y = np.arange(len(observers))
    fig, ax = plt.subplots(figsize=(6, 1.2 + 0.2 * len(observers)))
    ax.barh(y - 0.2, ours, height=0.4, label="ours (median step, this machine"
            + (", jobs in parallel)" if parallel else ")"))
    if np.isfinite(theirs).any():
        ax.barh(y + 0.2, theirs, height=0.4, label="paper (MATLAB)")
    ax.set_xscale("log")
    ax.set_yticks(y, list(observers), fontsize=7)
    ax.invert_yaxis()
    ax.set_xlabel("time per step [ms]")
    ax.set_title(f"{scenario}: per-step time", fontsize=9)
    ax.legend(fontsize=7)
    fig.tight_layout()
    return save_figure(fig, base)


def history(table: pd.DataFrame, scenario: str, base: Path) -> list[Path]:
    """Two panels over the commits: average relative RMS (log) and violations, one line per
    observer."""
    g = table[table["scenario"] == scenario]
    commits = list(dict.fromkeys(table["commit"]))
    x = {c: i for i, c in enumerate(commits)}
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(9, 6), sharex=True,
                                   gridspec_kw={"height_ratios": [3, 1]})
    cmap = plt.get_cmap("tab20")
    for k, (obs, o) in enumerate(g.groupby("observer", sort=False)):
        style = "-" if k < 20 else "--"
        xs = [x[c] for c in o["commit"]]
        ax1.plot(xs, o["rel_rms"], style, marker="o", ms=3, color=cmap(k % 20), label=obs)
        ax2.plot(xs, o["violations"].fillna(0), style, marker="o", ms=3, color=cmap(k % 20))
    ax1.set_yscale("log")
    ax1.set_ylabel("avg relative RMS")
    ax1.set_title(f"{scenario}: golden summaries over the commits", fontsize=9)
    ax1.legend(fontsize=6, ncol=2, loc="center left", bbox_to_anchor=(1.01, 0.5))
    ax2.set_ylabel("violations")
    ax2.set_xticks(range(len(commits)), [c[:7] for c in commits], rotation=45, fontsize=7)
    ax2.set_xlabel("commit (oldest first)")
    fig.tight_layout()
    return save_figure(fig, base)


def scaling(df: pd.DataFrame, variants: Sequence[str], realtime_ms: float,
            base: Path) -> list[Path]:
    """Log-log plot of step + hull time (``total_ms``) against n per observer, one panel per
    variant, with the real-time limit."""
    fig, axes = plt.subplots(1, len(variants), figsize=(6.5 * len(variants), 5), squeeze=False)
    for ax, variant in zip(axes[0], variants, strict=True):
        g = df[(df["variant"] == variant) & (df["status"] == "ok")]
        colors = plt.get_cmap("tab20").colors
        for k, name in enumerate(table_order(g["observer"].unique())):
            h = g[g["observer"] == name].sort_values("n")
            ax.loglog(h["n"], h["total_ms"], marker="osD^v"[k % 5], color=colors[k % 20],
                      label=name)
        if not len(g):
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.set_xlim(min(df["n"]), max(df["n"]))
            ax.text(0.5, 0.4, "no observer ran (see the report)", ha="center",
                    transform=ax.transAxes)
        ax.axhline(realtime_ms, color="k", linestyle="--", linewidth=1.2,
                   label=f"real time ({realtime_ms:g} ms)")
        ax.set_title(f"{variant} n-tank")
        ax.set_xlabel("states n")
        ax.set_ylabel("step + hull time per step [ms]")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7, ncol=2, loc="lower right")
    fig.tight_layout()
    return save_figure(fig, base, dpi=110)


def datadriven(steps: np.ndarray, x_true: np.ndarray, bounds: Mapping[str, tuple],
               panels: Sequence[tuple[Sequence[str], str]], polygons: Mapping[str, np.ndarray],
               snapshot: int, colors: Mapping[str, str], base: Path) -> list[Path]:
    """The figure of the data-driven study (like Alanwar et al.'s Figs. 2-3): per panel of
    ``panels`` (observer names, title) the bounds of x1 minus the true x1 over the steps
    (``bounds[name] = (lo, hi)``, first column used), and the sets at step ``snapshot`` as
    polygons (``polygons[name]``: vertices, one per row) with the true state."""
    fig, axes = plt.subplots(1, len(panels) + 1, figsize=(15, 4.5))
    for ax, (names, title) in zip(axes, panels, strict=False):
        for name in names:
            lo, hi = bounds[name]
            label = name + (" 3 sigma" if name.startswith("KF") else "")
            ax.plot(steps, lo[:, 0] - x_true[:, 0], color=colors[name], lw=1.2, label=label)
            ax.plot(steps, hi[:, 0] - x_true[:, 0], color=colors[name], lw=1.2)
        ax.axhline(0.0, color="k", lw=0.8, label="true x1")
        ax.set(xlabel="step k", ylabel="bound of x1 minus true x1",
               title=f"bounds of x1, {title}", ylim=(-4, 4))
        ax.legend(fontsize=7, ncol=2)
    ax = axes[-1]
    for name, P in polygons.items():
        ax.fill(P[:, 0], P[:, 1], alpha=0.25, color=colors[name], label=name)
        ax.plot(np.append(P[:, 0], P[0, 0]), np.append(P[:, 1], P[0, 1]), color=colors[name],
                lw=1)
    ax.plot(*x_true[snapshot], "k*", ms=10, label="true state")
    ax.set(xlabel="x1", ylabel="x2", title=f"sets at step {snapshot}")
    ax.set_aspect("equal")
    ax.legend(fontsize=8)
    fig.tight_layout()
    return save_figure(fig, base)

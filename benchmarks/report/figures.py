"""Every figure of the harness (matplotlib, drawn off screen), and the one way to save one.

Callers pass data (data frames or arrays) and a base path; each function draws, saves the
figure as ``base.png`` and ``base.pdf`` with :func:`save_figure` and returns both paths
(``None`` where there is nothing to draw).  This is the only module of ``benchmarks/`` that
imports matplotlib.

* :func:`observer_bounds` -- one observer's interval bounds over time with the true state,
  one panel per state (the figures linked from ``report.md``);
* :func:`bounds_and_radii` -- every state's bounds and radius (log scale) over time, every
  observer a layer the HTML page shows or hides (inline SVG, :class:`LayeredFigure`), extra
  bands optional (``bands={"exact": (lo, hi)}``);
* :func:`frontier` -- gap to the exact floor against cost per setting, Pareto front
  (frontier study);
* :func:`heat_map` -- a ratio per observer and state with its reference (HTML report);
* :func:`step_times` -- per-step times on a log scale beside the papers' (HTML report);
* :func:`history` -- the golden summaries over the commits (``setobs-bench history``);
* :func:`scaling` -- step + hull time against the number of states (scaling study);
* :func:`datadriven` -- bounds and sets of the data-driven study (Alanwar et al. 2022).
"""

from __future__ import annotations

import io
import re
import textwrap
import warnings
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.colors  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import matplotlib.ticker  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from observers.registry import table_order  # noqa: E402

from ..io import atomic_write_with  # noqa: E402

#: resolution of the PNG files (dots per inch)
DPI = 100
#: panels of :func:`observer_bounds` (the first states)
MAX_FIGURE_STATES = 6


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


@dataclass(frozen=True)
class Layer:
    """One selectable layer of a :class:`LayeredFigure` (an observer, the true state or an
    extra band): its key (``layer-K`` is the class of its SVG groups), name, colour, SVG dash
    pattern (for a legend swatch), whether it is shown at first, and a note (violations)."""

    key: str
    name: str
    color: str
    dash: str
    visible: bool
    kind: str = "observer"
    note: str = ""


@dataclass(frozen=True)
class LayeredFigure:
    """A figure whose layers can be shown and hidden in the page: ``svg`` is inline SVG text
    in which every artist of layer ``L`` is a ``<g class="layer L">`` (hidden ones with
    ``display:none``); ``paths`` are the PNG and PDF of the first view (the visible layers)."""

    svg: str
    layers: list[Layer]
    paths: list[Path]


#: line styles of the observer layers (cycled after the colours, so that curves that coincide,
#: e.g. CZN-A, CZN-B and CZN-MV, stay distinguishable) and their SVG dash patterns
LINE_STYLES = (("-", ""), ("--", "6,3"), (":", "1.5,2.5"), ("-.", "6,2,1.5,2"))
#: colour of the bands (``bands=``) and of the violation marks
BAND_COLORS = ("0.55", "tab:olive", "tab:cyan")
VIOLATION_COLOR = "red"
#: points per curve at most; longer records are drawn as a min/max envelope per bucket
MAX_POINTS_PER_FIGURE = 400_000
#: states per row of :func:`bounds_and_radii` above 8 states (two bounds-radius pairs)
WIDE_STATES = 8


def _log_ticks(axis) -> None:
    """Plain labels at 1, 2 and 5 of each decade of a log axis, no minor labels (matplotlib's
    default labels the minor ticks of short ranges, which overlap)."""
    axis.set_major_locator(matplotlib.ticker.LogLocator(base=10, subs=(1.0, 2.0, 5.0)))
    axis.set_major_formatter(matplotlib.ticker.FuncFormatter(lambda v, _: f"{v:g}"))
    axis.set_minor_formatter(matplotlib.ticker.NullFormatter())


def _style(k: int) -> tuple[str, str, str]:
    """Colour, matplotlib line style and SVG dash pattern of observer layer ``k``."""
    colors = plt.get_cmap("tab10").colors
    ls, dash = LINE_STYLES[(k // len(colors)) % len(LINE_STYLES)]
    return matplotlib.colors.to_hex(colors[k % len(colors)]), ls, dash


def _buckets(n_steps: int, max_points: int) -> np.ndarray | None:
    """Bucket boundaries for an envelope of ``max_points`` points, ``None`` if all fit."""
    if n_steps <= max_points:
        return None
    return np.linspace(0, n_steps, max(max_points // 2, 2) + 1).astype(int)


def _envelope(x: np.ndarray, edges: np.ndarray | None, how: str) -> np.ndarray:
    """``x`` (steps x states) reduced per bucket by ``how`` (``min``/``max``/``first``)."""
    if edges is None:
        return x
    parts = [x[a:b] for a, b in zip(edges[:-1], edges[1:], strict=True) if b > a]
    if how == "first":
        return np.array([q[0] for q in parts])
    f = np.nanmin if how == "min" else np.nanmax
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return np.array([f(q, axis=0) for q in parts])


def _layer_svg(svg: str, layers: Sequence[Layer]) -> str:
    """Matplotlib's SVG made inline and selectable: no XML prologue, scalable width, each
    ``<g id="KEY__j">`` group of a layer's artists becomes ``<g class="layer KEY">`` (hidden
    layers ``display:none``), coordinates rounded to 0.1 pt."""
    svg = svg[svg.index("<svg"):]
    svg = re.sub(r'<svg([^>]*?) width="[\d.]+pt" height="[\d.]+pt"',
                 r'<svg\1 width="100%" preserveAspectRatio="xMinYMin meet"', svg, count=1)
    hidden = {la.key for la in layers if not la.visible}

    def group(m: re.Match) -> str:
        key = m.group(1)
        style = ' style="display:none"' if key in hidden else ""
        return f'<g class="layer {key}" data-layer="{key}"{style}>'

    svg = re.sub(r'<g id="(layer-\d+)__\d+">', group, svg)
    # path coordinates to 0.1 pt (text, e.g. tick labels, untouched)
    return re.sub(r'(\sd=")([^"]*)"',
                  lambda m: m.group(1) + re.sub(r"(\d+\.\d)\d+", r"\1", m.group(2)) + '"', svg)


def _fit_first_view(ax, bounds: list[tuple[np.ndarray, np.ndarray]], i: int) -> None:
    """The y-range of a bounds panel: that of the observers shown at first (and the true
    state), so that loose observers shown later do not squash the tight ones (their curves are
    clipped; the radius panels show every observer at full range)."""
    vals = [v[:, i] for pair in bounds for v in pair]
    vals = np.concatenate(vals) if vals else np.array([])
    vals = vals[np.isfinite(vals)]
    if not vals.size:
        return
    # the first step holds the initial set, often far wider than the rest: skip it unless
    # it is all there is
    lo, hi = float(vals.min()), float(vals.max())
    rest = [np.concatenate([v[1:, i] for v in pair]) for pair in bounds]
    rest = np.concatenate(rest) if rest else np.array([])
    rest = rest[np.isfinite(rest)]
    if rest.size:
        lo, hi = float(rest.min()), float(rest.max())
    for line in ax.get_lines():
        if line.get_gid() and line.get_label() == "_truth":
            y = np.asarray(line.get_ydata(), float)
            y = y[np.isfinite(y)]
            if y.size:
                lo, hi = min(lo, float(y.min())), max(hi, float(y.max()))
    pad = 0.08 * (hi - lo) if hi > lo else max(abs(hi), 1.0) * 0.1
    ax.set_ylim(lo - pad, hi + pad)


@dataclass(frozen=True)
class BoundsView:
    """What :func:`bounds_and_radii` shows beside the observers' bounds.

    Attributes
    ----------
    visible : collection of str, optional
        The observers shown at first (default: all); the others are drawn hidden. Observers
        with a containment violation are always shown at first.
    bands : mapping of str to (lo, hi), optional
        Extra bands per state, e.g. ``{"exact": (lo, hi)}`` with ``lo`` and ``hi`` arrays of
        shape (steps, states) over the record's time steps: drawn filled behind the bounds and
        as a radius curve, each a selectable layer named by its key.
    title : str
        Figure title.
    """

    visible: Collection[str] | None = None
    bands: Mapping[str, tuple[np.ndarray, np.ndarray]] | None = None
    title: str = ""


def bounds_and_radii(runs: pd.DataFrame, scenario: str, observers: Sequence[str],
                     state_names: Sequence[str], base: Path,
                     view: BoundsView = BoundsView()) -> LayeredFigure | None:
    """Every state's bounds over time (left) and interval radius on a log scale (right), one
    row per state (two states per row above :data:`WIDE_STATES`), each observer a selectable
    layer, with the true state and the steps of any containment violation marked.

    Parameters
    ----------
    runs : pandas.DataFrame
        ``runs.csv`` rows (``scenario, observer, t, state, lo, hi, x_true, in_set``).
    scenario : str
        The scenario to draw.
    observers : sequence of str
        The observers (labels) to draw, in legend order; those without finite bounds are left
        out.
    state_names : sequence of str
        Axis labels of the states (default ``x1, x2, ...``).
    base : Path
        ``base.png`` and ``base.pdf`` get the first view (the visible layers).
    view : BoundsView
        The observers shown at first, extra bands and the title.

    Returns
    -------
    LayeredFigure or None
        ``None`` where no observer has finite bounds on ``scenario``.
    """
    g = runs[runs["scenario"] == scenario]
    g = g[g["observer"].isin(list(observers))]
    if g.empty:
        return None
    plot = _BoundsPlot(g, observers, view)
    if not plot.data:
        return None
    n = plot.n
    names = [state_names[i] if i < len(state_names) else f"x{i + 1}" for i in range(n)]
    per_row = 2 if n > WIDE_STATES else 1
    rows = -(-n // per_row)
    fig, axes = plt.subplots(rows, 2 * per_row, figsize=(14, 0.6 + 2.3 * rows), squeeze=False,
                             sharex=True)
    for i in range(n):
        ax_b, ax_r = axes[i // per_row, 2 * (i % per_row)], axes[i // per_row,
                                                                  2 * (i % per_row) + 1]
        plot.draw_state(i, ax_b, ax_r)
        _label_state(ax_b, ax_r, names[i])
    for ax in axes[-1]:
        ax.set_xlabel("t [s]", fontsize=8)
    for j in range(n, rows * per_row):  # an empty slot of the last row
        axes[-1, 2 * (j % per_row)].set_visible(False)
        axes[-1, 2 * (j % per_row) + 1].set_visible(False)
    if view.title:
        fig.suptitle(view.title, fontsize=9, x=0.01, ha="left")
    fig.tight_layout()
    buf = io.StringIO()
    with plt.rc_context({"svg.fonttype": "none", "svg.hashsalt": str(base)}):
        fig.savefig(buf, format="svg", metadata={"Date": None})
    svg = _layer_svg(buf.getvalue(), plot.layers)
    for la in plot.layers:
        for a in plot.artists[la.key]:
            a.set_visible(la.visible)
    return LayeredFigure(svg, plot.layers, save_figure(fig, base))


def _label_state(ax_b, ax_r, name: str) -> None:
    """Titles, scales and ticks of one state's bounds and radius axes."""
    ax_b.set_ylabel(name, fontsize=8)
    ax_b.set_title(f"{name}: bounds", fontsize=8, loc="left")
    ax_r.set_yscale("log")
    _log_ticks(ax_r.yaxis)
    ax_r.set_title(f"{name}: interval radius (log scale)", fontsize=8, loc="left")
    for ax in (ax_b, ax_r):
        ax.tick_params(labelsize=7)
        ax.grid(True, which="major", alpha=0.25)


class _BoundsPlot:
    """The data and layers of :func:`bounds_and_radii` (the observers' bounds on the time
    grid, the true state, the bands) and the drawing of one state."""

    def __init__(self, g: pd.DataFrame, observers: Sequence[str], view: BoundsView):
        self.t_all = np.sort(g["t"].unique())
        self.n = int(g["state"].max()) + 1
        self.data, self.truth = {}, None
        for obs in observers:
            o = g[g["observer"] == obs]
            if o.empty or not np.isfinite(o["lo"].to_numpy(float)).any():
                continue
            # a violation: the set missed the true state at that step (exact test, ``in_set``)
            miss = self._grid(o.assign(_bad=(o["in_set"] == 0).astype(float)), "_bad")
            self.data[obs] = (self._grid(o, "lo"), self._grid(o, "hi"),
                              np.nan_to_num(miss).any(axis=1))
            if self.truth is None and np.isfinite(o["x_true"].to_numpy(float)).any():
                self.truth = self._grid(o, "x_true")
        if not self.data:
            return
        self.bands = dict(view.bands or {})
        budget = max(MAX_POINTS_PER_FIGURE // max(3 * self.n * (len(self.data)
                                                                + len(self.bands)), 1), 50)
        self.edges = _buckets(len(self.t_all), budget)
        self.t = _envelope(self.t_all[:, None], self.edges, "first")[:, 0]
        self.layers = self._layers(view.visible)
        self.by_name = {la.name: la for la in self.layers}
        self.artists: dict[str, list] = {la.key: [] for la in self.layers}
        self._count = 0

    def _grid(self, frame: pd.DataFrame, column: str) -> np.ndarray:
        piv = frame.pivot_table(index="t", columns="state", values=column, aggfunc="first",
                                dropna=False)
        return piv.reindex(index=self.t_all, columns=range(self.n)).to_numpy(float)

    def _layers(self, visible: Collection[str] | None) -> list[Layer]:
        """One layer per observer, band and the true state, in drawing order."""
        layers: list[Layer] = []
        shown = set(self.data) if visible is None else set(visible)
        for k, obs in enumerate(self.data):
            color, _, dash = _style(k)
            bad = self.data[obs][2]
            note = f"{int(bad.sum())} violating steps" if bad.any() else ""
            layers.append(Layer(f"layer-{len(layers)}", obs, color, dash,
                                obs in shown or bad.any(), "observer", note))
        for j, name in enumerate(self.bands):
            layers.append(Layer(f"layer-{len(layers)}", name,
                                matplotlib.colors.to_hex(BAND_COLORS[j % len(BAND_COLORS)]),
                                "", True, "band"))
        if self.truth is not None:
            layers.append(Layer(f"layer-{len(layers)}", "true state", "#000000", "3,2", True,
                                "truth"))
        return layers

    def _gid(self, name: str) -> str:
        self._count += 1
        return f"{self.by_name[name].key}__{self._count}"

    def draw_state(self, i: int, ax_b, ax_r) -> None:
        """State ``i``: the bands, every observer's bounds and radius (with its violations)
        and the true state; the first view fitted to the visible layers."""
        t, edges, gid = self.t, self.edges, self._gid
        for j, (name, (blo, bhi)) in enumerate(self.bands.items()):
            lo_b = _envelope(np.asarray(blo, float), edges, "min")[:, i]
            hi_b = _envelope(np.asarray(bhi, float), edges, "max")[:, i]
            color = BAND_COLORS[j % len(BAND_COLORS)]
            a = ax_b.fill_between(t, lo_b, hi_b, color=color, alpha=0.3, lw=0, gid=gid(name))
            (b,) = ax_r.plot(t, np.where(hi_b > lo_b, (hi_b - lo_b) / 2, np.nan), color=color,
                             lw=2.5, alpha=0.6, gid=gid(name))
            self.artists[self.by_name[name].key] += [a, b]
        for k, obs in enumerate(self.data):
            self._draw_observer(i, (ax_b, ax_r), k, obs)
        if self.truth is not None:
            x_i = _envelope(self.truth, edges, "first")[:, i]
            (a,) = ax_b.plot(t, x_i, color="k", lw=1.1, ls=(0, (3, 2)), gid=gid("true state"),
                             label="_truth")
            self.artists[self.by_name["true state"].key].append(a)
        _fit_first_view(ax_b, [self.data[la.name][:2] for la in self.layers
                               if la.kind == "observer" and la.visible]
                        + [tuple(np.asarray(b, float) for b in pair)
                           for pair in self.bands.values()], i)

    def _draw_observer(self, i: int, axes: tuple, k: int, obs: str) -> None:
        """Observer ``obs`` (the ``k``-th) on state ``i``: bounds, radius, violations."""
        ax_b, ax_r = axes
        t, edges, gid = self.t, self.edges, self._gid
        lo, hi, bad = self.data[obs]
        color, ls, _ = _style(k)
        lo_i = _envelope(lo, edges, "min")[:, i]
        hi_i = _envelope(hi, edges, "max")[:, i]
        radius = (hi_i - lo_i) / 2
        radius = np.where(radius > 0, radius, np.nan)
        key = self.by_name[obs].key
        (a,) = ax_b.plot(t, lo_i, color=color, ls=ls, lw=0.9, gid=gid(obs))
        (b,) = ax_b.plot(t, hi_i, color=color, ls=ls, lw=0.9, gid=gid(obs))
        (c,) = ax_r.plot(t, radius, color=color, ls=ls, lw=0.9, gid=gid(obs))
        self.artists[key] += [a, b, c]
        if bad.any():
            steps_bad = np.flatnonzero(bad)
            xs = self.t_all[steps_bad]
            ref = self.truth[steps_bad, i] if self.truth is not None else lo[steps_bad, i]
            (d,) = ax_b.plot(xs, ref, ls="none", marker="x", ms=5, mew=1.2,
                             color=VIOLATION_COLOR, gid=gid(obs))
            r_bad = (hi[steps_bad, i] - lo[steps_bad, i]) / 2
            (e,) = ax_r.plot(xs, np.where(r_bad > 0, r_bad, np.nan), ls="none",
                             marker="x", ms=5, mew=1.2, color=VIOLATION_COLOR, gid=gid(obs))
            self.artists[key] += [d, e]


def heat_map(values: pd.DataFrame, title: str, reference: str,
             base: Path, label: str = "log10 v_i") -> list[Path] | None:
    """A ratio per observer and state (``values``: observers as rows in table order, states as
    columns, e.g. the v_i of the scenario table) as a heat map with a log colour scale; the
    title names the reference of the ratios."""
    vals = values.to_numpy(float)
    if not np.isfinite(vals).any():
        return None
    n_obs, n = vals.shape
    fig, ax = plt.subplots(figsize=(min(3.5 + 0.5 * n, 13), 1.5 + 0.2 * n_obs))
    with np.errstate(divide="ignore", invalid="ignore"):
        logs = np.log10(vals)
    im = ax.imshow(logs, cmap="viridis_r", aspect="auto")
    ax.set_yticks(range(n_obs), list(values.index), fontsize=7)
    ax.set_xticks(range(n), [str(c) for c in values.columns], fontsize=7)
    if n <= 10:
        mid = np.nanmean(logs[np.isfinite(logs)])
        for (i, j), v in np.ndenumerate(vals):
            if np.isfinite(v) and v > 0:
                ax.text(j, i, f"{v:.3g}", ha="center", va="center", fontsize=6,
                        color="w" if np.log10(v) > mid else "k")
    cb = fig.colorbar(im, ax=ax)
    cb.set_label(label, fontsize=7)
    width = max(int(fig.get_figwidth() * 14), 40)
    ax.set_title(textwrap.fill(title, width) + "\n" + textwrap.fill(reference, width),
                 fontsize=8, loc="left")
    fig.tight_layout()
    return save_figure(fig, base)


def step_times(observers: Sequence[str], ours: np.ndarray, theirs: np.ndarray, scenario: str,
               parallel: bool, base: Path, source: str | None = None) -> list[Path] | None:
    """Per-step time (median ms, log scale) of every observer, beside the published time
    (``theirs``: NaN where the paper has none; ``source`` names the paper table)."""
    if not np.isfinite(ours).any():
        return None
    y = np.arange(len(observers))
    fig, ax = plt.subplots(figsize=(7, 1.4 + 0.2 * len(observers)))
    ax.barh(y - 0.2, ours, height=0.4, label="ours (median step, this machine"
            + (", jobs in parallel)" if parallel else ")"))
    if np.isfinite(theirs).any():
        ax.barh(y + 0.2, theirs, height=0.4,
                label=f"{source or 'paper'} (MATLAB, i7-8565U)")
    ax.set_xscale("log")
    _log_ticks(ax.xaxis)
    ax.set_yticks(y, list(observers), fontsize=7)
    ax.invert_yaxis()
    ax.set_xlabel("time per step [ms]")
    ax.set_title(f"{scenario}: per-step time" + (
        f" beside {source}" if np.isfinite(theirs).any() else " (no published times)"),
        fontsize=9, loc="left")
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


#: the x axes of the frontier figure: column -> label
FRONTIER_AXES = {"cost_ratio": "cost per step (step + hull) / Kalman step",
                 "memory": "memory of the set (floating-point values, steady state)"}


def frontier(df: pd.DataFrame, base: Path, x: str = "cost_ratio") -> list[Path]:
    """Log-log plot of the gap to the exact floor against the cost (ratio to a Kalman step)
    or, ``x="memory"``, against the memory of the estimated set, one panel per record: each
    observer's settings joined in knob order and labelled with the knob's value, the Pareto
    front of gap and cost as a black staircase (on the cost axis only)."""
    records = list(dict.fromkeys(df["record"]))
    fig, axes = plt.subplots(1, max(1, len(records)), figsize=(6 * max(1, len(records)), 5),
                             squeeze=False)
    colors = plt.get_cmap("tab10").colors
    for ax, record in zip(axes[0], records, strict=False):
        g = df[(df["record"] == record) & (df["status"] == "ok")]
        for k, name in enumerate(dict.fromkeys(g["observer"])):
            h = g[g["observer"] == name]
            ax.loglog(h[x], h["gap"], marker="osD^v<>"[k % 7], ms=5,
                      color=colors[k % 10], label=name, linewidth=1)
            for r in h.itertuples(index=False):
                ax.annotate(str(r.value), (getattr(r, x), r.gap), fontsize=6,
                            xytext=(3, 3), textcoords="offset points", color=colors[k % 10])
        f = g[g["pareto"].astype(bool)].sort_values("cost_ratio")
        if len(f) and x == "cost_ratio":
            ax.step(f["cost_ratio"], f["gap"], where="post", color="k", linewidth=1.5,
                    alpha=0.6, label="Pareto front")
            ax.scatter(f["cost_ratio"], f["gap"], s=60, facecolors="none", edgecolors="k")
        if not len(g):
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.text(0.5, 0.5, "no setting ran (see the report)", ha="center",
                    transform=ax.transAxes)
        ax.set_title(record)
        ax.set_xlabel(FRONTIER_AXES[x])
        ax.set_ylabel("gap to the exact floor (1 = optimal)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7, loc="upper right")
    fig.tight_layout()
    return save_figure(fig, base, dpi=110)


@dataclass(frozen=True)
class DataDrivenRuns:
    """The runs drawn by :func:`datadriven`.

    Attributes
    ----------
    steps : (N,) array
        The time steps.
    x_true : (N, n) array
        The true states.
    bounds : mapping
        Observer name -> ``(lo, hi)`` (N x n; the first column is drawn).
    polygons : mapping
        Observer name -> the vertices of its set at step ``snapshot``, one per row.
    snapshot : int
        The step of the polygons.
    """

    steps: np.ndarray
    x_true: np.ndarray
    bounds: Mapping[str, tuple]
    polygons: Mapping[str, np.ndarray]
    snapshot: int


def datadriven(runs: DataDrivenRuns, panels: Sequence[tuple[Sequence[str], str]],
               colors: Mapping[str, str], base: Path) -> list[Path]:
    """The figure of the data-driven study (like Alanwar et al.'s Figs. 2-3): per panel of
    ``panels`` (observer names, title) the bounds of x1 minus the true x1 over the steps,
    and the sets at the snapshot step as polygons with the true state (``runs``)."""
    steps, x_true, bounds = runs.steps, runs.x_true, runs.bounds
    polygons, snapshot = runs.polygons, runs.snapshot
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


def noise_grid(curves: pd.DataFrame, value: str, label: str, record: str,
               base: Path) -> list[Path]:
    """The noise-level grid of one record: per axis (the set scaled: W, V, X0 or all), the
    best ``value`` of each observer family against the scale factor, log-log
    (``curves``: columns ``axis``, ``family``, ``scale`` and ``value``)."""
    axes_names = list(dict.fromkeys(curves["axis"]))
    fig, axes = plt.subplots(1, max(1, len(axes_names)), figsize=(4.2 * len(axes_names), 4),
                             squeeze=False, sharey=True)
    families = sorted(curves["family"].unique())
    colors = plt.get_cmap("tab10").colors
    for ax, axis in zip(axes[0], axes_names, strict=False):
        g = curves[curves["axis"] == axis]
        for k, family in enumerate(families):
            h = g[g["family"] == family].sort_values("scale")
            if len(h):
                ax.loglog(h["scale"], h[value], marker="osD^v<>"[k % 7],
                          color=colors[k % 10], label=family)
        ax.set_title(f"{record}: {'W, V and X0' if axis == 'all' else axis} scaled")
        ax.set_xlabel("scale factor")
        ax.grid(True, which="both", alpha=0.3)
    axes[0][0].set_ylabel(f"best {label} of the family")
    axes[0][-1].legend(fontsize=7, loc="best")
    fig.tight_layout()
    return save_figure(fig, base, dpi=110)


def rank_distributions(ranks: pd.DataFrame, base: Path) -> list[Path]:
    """Box plots of each observer's rank over the realisations (1 = the tightest), one panel
    per scenario, observers by median rank (``ranks``: columns ``scenario``, ``observer``,
    ``rank``)."""
    scenarios = list(dict.fromkeys(ranks["scenario"]))
    cols = min(3, len(scenarios))
    rows = -(-len(scenarios) // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(6.2 * cols, 4.2 * rows), squeeze=False)
    for ax, scenario in zip(axes.ravel(), scenarios, strict=False):
        g = ranks[ranks["scenario"] == scenario]
        order = g.groupby("observer")["rank"].median().sort_values(kind="stable").index
        data = [g[g["observer"] == name]["rank"].to_numpy(float) for name in order]
        ax.boxplot(data, vert=True, showfliers=True, flierprops={"markersize": 2})
        ax.set_xticks(range(1, len(order) + 1), order, rotation=90, fontsize=6)
        ax.set_title(f"{scenario}: rank over the realisations")
        ax.set_ylabel("rank (1 = tightest)")
        ax.grid(True, axis="y", alpha=0.3)
    for ax in axes.ravel()[len(scenarios):]:
        ax.set_visible(False)
    fig.tight_layout()
    return save_figure(fig, base, dpi=110)

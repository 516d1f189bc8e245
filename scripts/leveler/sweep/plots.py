"""Plots a person reads at a glance: for each figure of the study's [plot]
figures (by default return time, overshoot, air used as the compressor's
on-time, and switchings), a heat map over two swept keys (one
panel per combination of the other dimensions: config, scenario, algorithm,
other keys, on one colour scale), or lines over one swept key.
"""
from __future__ import annotations

import itertools
import math
import os

from . import figures


def _facets(rows, dims):
    """The combinations of ``dims`` present in ``rows``, in row order, and their rows."""
    groups = {}
    for r in rows:
        groups.setdefault(tuple(r[d] for d in dims), []).append(r)
    return groups


def _label(dims, combo):
    parts = []
    for d, v in zip(dims, combo):
        parts.append(f"alg {v}" if d == "algorithm" else str(v) if d in ("config", "scenario") else f"{d} = {v}")
    return ", ".join(parts) or "all points"


def _value(row, name):
    v = row.get(name)
    label, unit, factor = figures.LABELS[name]
    return float("nan") if v is None or row.get("error") else v * factor


def axes_of(study):
    """The swept keys to plot over: [plot] x/y, else the first two with several values."""
    keys = study.plot_axes or [k for k, values in study.vary if len(values) > 1]
    return keys[:2]


def other_dims(study, rows, axes):
    fixed = ["config", "scenario", "algorithm"] + [k for k in study.keys if k not in axes]
    return [d for d in fixed if len({r[d] for r in rows}) > 1]


def heatmap(rows, name, x, y, dims, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    groups = _facets(rows, dims)
    xs = sorted({r[x] for r in rows})
    ys = sorted({r[y] for r in rows})
    vals = [_value(r, name) for r in rows if math.isfinite(_value(r, name))]
    lo, hi = (min(vals), max(vals)) if vals else (0.0, 1.0)
    ncol = min(len(groups), 2)
    nrow = math.ceil(len(groups) / ncol)
    fig, axs = plt.subplots(nrow, ncol, figsize=(5.2 * ncol, 3.9 * nrow), squeeze=False, constrained_layout=True)
    label, unit, _ = figures.LABELS[name]
    for ax, (combo, grp) in itertools.zip_longest(axs.flat, groups.items(), fillvalue=(None, None)):
        if combo is None:
            ax.set_axis_off()
            continue
        cell = {(r[x], r[y]): _value(r, name) for r in grp}
        grid = [[cell.get((xv, yv), float("nan")) for xv in xs] for yv in ys]
        im = ax.imshow(grid, origin="lower", aspect="auto", vmin=lo, vmax=hi if hi > lo else lo + 1, cmap="viridis")
        for (i, yv), (j, xv) in itertools.product(enumerate(ys), enumerate(xs)):
            v = grid[i][j]
            ax.text(j, i, "-" if not math.isfinite(v) else f"{v:.3g}", ha="center", va="center", fontsize=7,
                    color="white" if not math.isfinite(v) or v < lo + 0.6 * (hi - lo) else "black")
        ax.set_xticks(range(len(xs)), [str(v) for v in xs])
        ax.set_yticks(range(len(ys)), [str(v) for v in ys])
        ax.set_xlabel(x)
        ax.set_ylabel(y)
        ax.set_title(_label(dims, combo), fontsize=9)
    fig.colorbar(im, ax=axs, shrink=0.8, label=f"{label} ({unit})" if unit else label)
    fig.suptitle(f"{label}  (- : not defined, e.g. never back in the band)", fontsize=10)
    fig.savefig(path, dpi=90)
    plt.close(fig)


def lines(rows, name, x, dims, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6.4, 4.2), constrained_layout=True)
    for combo, grp in _facets(rows, dims).items():
        grp = sorted(grp, key=lambda r: r[x])
        ax.plot([r[x] for r in grp], [_value(r, name) for r in grp], marker="o", label=_label(dims, combo))
    label, unit, _ = figures.LABELS[name]
    ax.set_xlabel(x)
    ax.set_ylabel(f"{label} ({unit})" if unit else label)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    fig.savefig(path, dpi=90)
    plt.close(fig)


def plot_all(study, rows, out_dir):
    """The PNGs of a finished sweep; returns their paths (none without a swept key)."""
    axes = axes_of(study)
    if not axes or not rows:
        return []
    dims = other_dims(study, rows, axes)
    written = []
    for name in study.plot_figures:
        path = os.path.join(out_dir, f"{'heatmap' if len(axes) == 2 else 'lines'}-{name}.png")
        if len(axes) == 2:
            heatmap(rows, name, axes[0], axes[1], dims, path)
        else:
            lines(rows, name, axes[0], dims, path)
        written.append(path)
    return written

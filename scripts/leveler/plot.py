"""The report figure: height, pressures, actuators against time, and P2 against
height with the hysteresis lines (like the thesis's figure 20).

``plot_run(log, out_png, analysis=None, cfg=None, units="thesis")`` writes a
PNG atomically. Uses the Agg backend; no display needed.
"""

from __future__ import annotations

import io
import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from . import __version__  # noqa: E402
from . import config as config_mod  # noqa: E402
from . import events as events_mod  # noqa: E402
from . import runlog, thesis  # noqa: E402

_UNITS = {
    # name: (height scale from m, height label, pressure fn from Pa abs, pressure label)
    "thesis": (1.0 / thesis.M_PER_IN, "height (in)", thesis.pa_to_psia, "pressure (psia)"),
    "si": (1.0, "height (m)", lambda p: p / 1e3, "pressure (kPa abs)"),
}

_ACTUATORS = (("compressor", "compressor", "#d62728"), ("spring_valve", "spring valve", "#1f77b4"),
              ("vent_valve", "vent valve", "#2ca02c"), ("acc_valve", "accumulator valve", "#9467bd"))


def _load_levels(log, analysis):
    """Distinct load levels (N) in order of appearance."""
    levels = [float(log.load_n[0])]
    for e in analysis.load_events:
        if all(abs(e.after_n - lv) > 1.0 for lv in levels):
            levels.append(e.after_n)
    return levels


def _load_label(load_n, units):
    return f"{thesis.n_to_lb(load_n):.0f} lb" if units == "thesis" else f"{load_n:.0f} N"


def _runs(flag):
    """(start index, length) of runs where ``flag`` is true."""
    f = np.concatenate([[False], flag, [False]]).astype(np.int8)
    d = np.diff(f)
    starts = np.flatnonzero(d == 1)
    ends = np.flatnonzero(d == -1)
    return list(zip(starts, ends - starts))


def _mark_faults(ax, log):
    """Red spans where the supervisor held a latched fault (format 3 logs)."""
    bits = np.nan_to_num(log.latched_fault_bits, nan=0.0)
    t = log.t_s
    for n, (i, length) in enumerate(_runs(bits > 0)):
        end = t[min(i + length, len(t) - 1)]
        ax.axvspan(t[i], end, color="#d62728", alpha=0.15, lw=0,
                   label="fault latched" if n == 0 else None)


def plot_run(log, out_png, analysis=None, cfg=None, units="thesis", title=None):
    """Draws the report figure for ``log`` into ``out_png`` (atomic write)."""
    if units not in _UNITS:
        raise ValueError(f"units must be one of {', '.join(_UNITS)}, not '{units}'")
    cfg = cfg or config_mod.default_config(log.config)
    if analysis is None:
        analysis = events_mod.analyze(log, events_mod.EventOptions(
            band_lower_m=cfg.band_lower_m, band_upper_m=cfg.band_upper_m))
    hs, hlabel, pconv, plabel = _UNITS[units]
    t = log.t_s
    h = log.height_m * hs

    fig = plt.figure(figsize=(15, 9.5), dpi=100, layout="constrained")
    gs = fig.add_gridspec(3, 2, width_ratios=(1.7, 1.0), height_ratios=(1.25, 1.25, 0.6))
    ax_h = fig.add_subplot(gs[0, 0])
    ax_p = fig.add_subplot(gs[1, 0], sharex=ax_h)
    ax_a = fig.add_subplot(gs[2, 0], sharex=ax_h)
    ax_ph = fig.add_subplot(gs[:, 1])

    # --- height ---------------------------------------------------------------
    band_lower, band_upper = cfg.band_lower_m * hs, cfg.band_upper_m * hs
    ax_h.axhspan(band_lower, band_upper, color="#2ca02c", alpha=0.15, lw=0, label="band")
    ax_h.plot(t, h, color="k", lw=1.0, label="height")
    for e in analysis.load_events:
        ax_h.axvline(e.t_s, color="0.5", ls=":", lw=1)
        ax_h.annotate(f"{'+' if e.delta_n > 0 else '-'}{_load_label(abs(e.delta_n), units)}",
                      (e.t_s, 1.0), xycoords=("data", "axes fraction"), xytext=(3, -12),
                      textcoords="offset points", fontsize=8, color="0.3")
    for ex in (analysis.step, analysis.removal):
        if ex is None or ex.t_rest_s is None:
            continue
        t_end = ex.t_leave_s if ex.t_leave_s is not None else t[-1]
        level = (ex.level_m if ex.level_m is not None else ex.extreme_m) * hs
        ax_h.plot([ex.t_rest_s, t_end], [level, level], color="#ff7f0e", lw=3, alpha=0.7,
                  solid_capstyle="butt")
        stuck = t_end - ex.t_rest_s
        ax_h.annotate(f"stuck {stuck:.1f} s", ((ex.t_rest_s + t_end) / 2, level),
                      xytext=(0, -12 if ex.direction > 0 else 6), textcoords="offset points",
                      ha="center", fontsize=8, color="#ff7f0e")
    _mark_faults(ax_h, log)
    ax_h.set_ylabel(hlabel)
    ax_h.grid(True, alpha=0.3)
    ax_h.legend(loc="lower right", fontsize=8)
    src = f"{log.config or 'run'} ({log.source})"
    ax_h.set_title(title or f"{src}: height", fontsize=10, loc="left")
    plt.setp(ax_h.get_xticklabels(), visible=False)

    # --- pressures ------------------------------------------------------------
    for name, label, color in (("p_pipe_pa", "P1 pipe", "#1f77b4"),
                               ("p_spring_pa", "P2 spring", "k"),
                               ("p_acc_pa", "P3 accumulator", "#9467bd")):
        p = log.column(name)
        if np.isfinite(p).any():
            ax_p.plot(t, pconv(p), color=color, lw=1.0 if name == "p_spring_pa" else 0.8,
                      label=label, alpha=1.0 if name == "p_spring_pa" else 0.8)
    ax_p.set_ylabel(plabel)
    ax_p.grid(True, alpha=0.3)
    if ax_p.lines:
        ax_p.legend(loc="upper right", fontsize=8)
    else:
        ax_p.text(0.5, 0.5, "no pressure measured", transform=ax_p.transAxes, ha="center")
    ax_p.set_title("pressures", fontsize=10, loc="left")
    plt.setp(ax_p.get_xticklabels(), visible=False)

    # --- actuators ------------------------------------------------------------
    rows = []
    dt_last = float(np.median(np.diff(t))) if len(t) > 1 else 0.01
    t_edges = np.append(t, t[-1] + dt_last)
    for name, label, color in _ACTUATORS:
        state = log.column(name)
        if not np.isfinite(state).any():
            continue
        y = len(rows)
        bars = [(t_edges[s], t_edges[s + n] - t_edges[s]) for s, n in _runs(state == 1.0)]
        ax_a.broken_barh(bars, (y - 0.35, 0.7), facecolors=color)
        unknown = [(t_edges[s], t_edges[s + n] - t_edges[s]) for s, n in _runs(~np.isfinite(state))]
        if unknown:
            ax_a.broken_barh(unknown, (y - 0.35, 0.7), facecolors="none", edgecolors="0.6",
                             hatch="///", lw=0)
        rows.append(label)
    ax_a.set_yticks(range(len(rows)), rows, fontsize=8)
    ax_a.set_ylim(-0.6, max(len(rows), 1) - 0.4)
    ax_a.invert_yaxis()
    ax_a.set_xlabel("time (s)")
    ax_a.grid(True, axis="x", alpha=0.3)
    ax_a.set_title("actuators (bar = on / open)", fontsize=10, loc="left")
    ax_a.set_xlim(t[0], t[-1])

    # --- P2 against height, with the hysteresis lines -----------------------------
    p2 = log.p_spring_pa
    finite = np.isfinite(p2)
    hmin, hmax = float(np.nanmin(log.height_m)), float(np.nanmax(log.height_m))
    span = max(hmax - hmin, 0.02)
    hh = np.linspace(hmin - 0.1 * span, hmax + 0.1 * span, 50)
    colors = ["#1f77b4", "#d62728", "#2ca02c", "#8c564b"]
    for k, load in enumerate(_load_levels(log, analysis)[:4]):
        up, down = cfg.hysteresis_lines(load)
        c = colors[k % len(colors)]
        lab = _load_label(load, units)
        ax_ph.plot(pconv(up(hh)), hh * hs, color=c, lw=1.2, label=f"UPlimit {lab}")
        ax_ph.plot(pconv(down(hh)), hh * hs, color=c, lw=1.2, ls="--", label=f"DPlimit {lab}")
    if finite.any():
        sc = ax_ph.scatter(pconv(p2[finite]), h[finite], c=t[finite], s=3, cmap="viridis",
                           zorder=3, lw=0)
        fig.colorbar(sc, ax=ax_ph, label="time (s)", shrink=0.6, pad=0.01)
        # The thesis's points A..H (figure 20).
        pts = []
        if analysis.height_before_step_m is not None and analysis.step is not None:
            pts.append(("A", analysis.step.event.t_s - 1e-9))
        for ex, names in ((analysis.step, "BCD"), (analysis.removal, "FGH")):
            if ex is None:
                continue
            for letter, when in zip(names, (ex.t_rest_s, ex.t_leave_s, ex.t_return_s)):
                if when is not None:
                    pts.append((letter, when))
        for letter, when in pts:
            x = np.interp(when, t[finite], pconv(p2[finite]))
            y = np.interp(when, t, h)
            ax_ph.plot(x, y, "o", ms=5, mfc="w", mec="k", zorder=4)
            ax_ph.annotate(letter, (x, y), xytext=(5, 3), textcoords="offset points",
                           fontsize=10, weight="bold", zorder=5)
    else:
        ax_ph.text(0.5, 0.5, "no spring pressure measured", transform=ax_ph.transAxes,
                   ha="center")
    ax_ph.axhspan(band_lower, band_upper, color="#2ca02c", alpha=0.15, lw=0)
    ax_ph.set_xlabel("P2 spring " + plabel)
    ax_ph.set_ylabel(hlabel)
    ax_ph.grid(True, alpha=0.3)
    ax_ph.legend(loc="upper right", fontsize=8)
    ax_ph.set_title("P2 against height, hysteresis lines of each load", fontsize=10, loc="left")

    # which code drew it, and which wrote the log (docs/log-format.md "# version:")
    fig.text(0.995, 0.002, f"leveler {__version__}; log by {log.meta.get('version', 'a version before 0.6.0')}",
             ha="right", va="bottom", fontsize=7, color="0.4")
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    plt.close(fig)
    runlog.write_text_atomic(os.fspath(out_png), buf.getvalue(), mode="wb")

"""The figures of one run log a sweep collects.

Two kinds, all SI:

* the event figures of the load step and the load removal (leveler.events,
  docs/events.md): ``time_return_after_step_s``, ``lowest_height_m``, ...;
* control figures over the whole run, as the controller scorecard defines
  them (docs/controller.md, host_sim/sim/ctlbench.c), from the log's columns:

  ``overshoot_m``        for each load event (leveler.events.find_load_events),
                         after the first entry into the band at least 1 s after
                         the event (entering sooner is the load's doing), the
                         farthest outside the band until the next event; the
                         largest over the events (0 when it never shoots out);
  ``switchings``         ticks on which any output (compressor, valves) changed;
  ``compressor_on_s``    the compressor's on-time: the measure of *air used* a
                         run log allows (it holds no air mass or flow; the
                         scorecard's vented air needs the plant's orifice model);
  ``vent_open_s``        the vent valve's open time (air blown off);
  ``outside_band_s``     time outside the band;
  ``latched_fault_bits`` the supervisor's latched faults at the end.

The height is the plant's true height when the log has it (a simulator's),
else the measured one.
"""
from __future__ import annotations

import numpy as np

from .. import events, runlog

ENTRY_AFTER_S = 1.0          # ctlbench.c LOAD_MOTION_S
CONTROL = ("overshoot_m", "switchings", "compressor_on_s", "vent_open_s", "outside_band_s",
           "latched_fault_bits")
NAMES = tuple(events.SUMMARY_KEYS) + CONTROL
INTEGER = ("switchings", "latched_fault_bits")
LABELS = {   # for plots: (label, unit, factor from SI)
    "time_return_after_step_s": ("return after the step", "s", 1.0),
    "time_return_after_removal_s": ("return after the removal", "s", 1.0),
    "overshoot_m": ("overshoot beyond the band", "mm", 1e3),
    "compressor_on_s": ("air used: compressor on-time", "s", 1.0),
    "switchings": ("switchings", "", 1.0),
    "lowest_height_m": ("lowest height after the step", "mm", 1e3),
    "highest_height_m": ("highest height after the removal", "mm", 1e3),
    "time_stuck_bottom_s": ("time stuck at the bottom", "s", 1.0),
    "time_stuck_top_s": ("time stuck at the top", "s", 1.0),
    "p2_breakaway_pa": ("P2 at break-away", "kPa abs", 1e-3),
    "p2_start_down_pa": ("P2 when it starts down", "kPa abs", 1e-3),
    "vent_open_s": ("vent open", "s", 1.0),
    "outside_band_s": ("time outside the band", "s", 1.0),
}


def _outside(h, lower, upper):
    return np.maximum(np.maximum(lower - h, h - upper), 0.0)


def _overshoot(t, off, load_events):
    starts = [e.index for e in load_events] or [0]
    ends = starts[1:] + [len(t)]
    worst = 0.0
    for (i0, i1), e in zip(zip(starts, ends), load_events or [None]):
        t_entry = (e.t_s if e else t[0]) + ENTRY_AFTER_S
        seg_off, seg_t = off[i0:i1], t[i0:i1]
        entries = np.flatnonzero((seg_off[1:] == 0.0) & (seg_off[:-1] > 0.0) & (seg_t[1:] >= t_entry)) + 1
        if entries.size:
            worst = max(worst, float(np.nanmax(seg_off[entries[0]:])))
    return worst


def _ticks(tick, mask):
    """Time of the ticks in ``mask`` (rounded to the nanosecond: a count of ticks)."""
    return round(tick * int(np.count_nonzero(mask)), 9)


def control_figures(log, band_lower_m, band_upper_m):
    """The control figures (CONTROL) of a run log."""
    t = np.asarray(log.t_s, dtype=float)
    h = log.true_height_m if np.isfinite(log.true_height_m).any() else log.height_m
    off = _outside(np.asarray(h, dtype=float), band_lower_m, band_upper_m)
    tick = float(np.median(np.diff(t))) if len(t) > 1 else 0.0
    on = {name: np.nan_to_num(getattr(log, name)) > 0
          for name in runlog.ACTUATORS}
    bits = sum(on[name].astype(int) << i for i, name in enumerate(on))
    faults = log.latched_fault_bits[np.isfinite(log.latched_fault_bits)]
    return {
        "overshoot_m": _overshoot(t, off, events.find_load_events(t, log.load_n)),
        "switchings": int(np.count_nonzero(np.diff(bits))),
        "compressor_on_s": _ticks(tick, on["compressor"]),
        "vent_open_s": _ticks(tick, on["vent_valve"]),
        "outside_band_s": _ticks(tick, off > 0.0),
        "latched_fault_bits": int(faults[-1]) if faults.size else None,
    }


def measure(log, band_lower_m, band_upper_m, names=NAMES):
    """The figures ``names`` of a run log (None where not defined)."""
    opts = events.EventOptions(band_lower_m=band_lower_m, band_upper_m=band_upper_m)
    every = dict(events.summarize(log, opts), **control_figures(log, band_lower_m, band_upper_m))
    return {name: every[name] for name in names}

"""Event figures of a load step and a load removal, as the thesis reports them.

The definitions (also in docs/events.md) are built to hold on a clean
simulator log and on a noisy, quantised rig log alike.

Preparation
  * Load events come from ``load_n`` (the operator's load, piecewise
    constant): an event starts at the first sample that leaves the previous
    load level and ends when the load stops changing; its size is the new
    level minus the old one. Changes smaller than ``step_min_n`` are ignored.
    The *load step* is the first event that adds load, the *load removal* the
    first event after it that takes load away. Each analysis window runs from
    its event to the next load event (or the end of the log).
  * Heights are smoothed by a moving median over
    ``smooth_s`` seconds (odd number of samples), which removes sensor noise
    and spikes and keeps plateaus, ramps and their corners exactly.
  * A pressure "at" a corner (coming to rest, leaving) is the value there of
    a straight line fitted, with one pass of outlier rejection, to the raw
    pressure over ``fit_s`` seconds on the resting side of the corner. Exact
    on a clean log; unbiased on a noisy one, where any centred filter is
    biased at a sharp turn of the pressure.
  * The rest tolerance is ``max(rest_tol_min_m, 5 * sigma_smoothed,
    1.5 * quantum)``: sigma from the median absolute second difference (zero
    on flats and straight ramps, so motion does not count as noise), shrunk
    by the median window; quantum is the smallest non-zero change of the raw
    height (an ADC step).

Load step (platform drops, rests, climbs back)
  * ``height_before_step_m``: median raw height over the ``before_s`` seconds
    before the step.
  * The bottom: the minimum of the smoothed height in the window, first
    reached at i_min. The platform is *at the bottom* while the smoothed height
    is within the rest tolerance of that minimum.
  * ``time_return_after_step_s``: from the step to the first time after i_min
    the smoothed height reaches the band's lower edge (linear interpolation
    between samples). None if it never does.
  * ``lowest_height_m``: the resting level, the median raw height of the
    samples whose smoothed height is within the tolerance of the minimum
    (before the return, if any).
  * Coming to rest (t_rest): the first time after the step the smoothed
    height is within the tolerance of the resting level. Break-away (t_break):
    the last time before the return (or the window end) it is. Both are then
    moved to where the motion just outside the tolerance (between 2 and 1
    tolerances from the level), extended in a straight line, meets the level,
    so the tolerance does not shorten the rest. t_break is None if the
    platform is still there when the window ends.
  * ``time_stuck_bottom_s`` = t_break - t_rest: "from coming to rest until it
    starts to move back".
  * ``p2_drop_stop_pa``: spring pressure at t_rest ("P2 when the drop
    stops").
  * ``p2_breakaway_pa``: spring pressure at t_break, the pressure that breaks
    the platform free (while stuck the compressor only raises it).
  * ``p2_after_climb_pa``: median spring pressure over the last ``settle_s``
    seconds of the window after the return into the band (the pressure the
    platform settles at after the climb); None without a return.

Load removal (platform jumps, rests at the top, comes down): the mirror image.
  * ``highest_height_m``: median raw height while at the top.
  * ``p2_jump_pa``: spring pressure when the platform comes to rest at the
    top.
  * ``time_stuck_top_s``: from coming to rest at the top until it starts down.
  * ``p2_start_down_pa``: spring pressure when it starts down.
  * ``time_return_after_removal_s``: from the removal to the first time after
    the top the smoothed height reaches the band's upper edge.

All values SI (m, Pa absolute, s); None where not defined (no such event, no
pressure measured, the log ends too soon).
"""

from __future__ import annotations

import dataclasses
import math
from typing import List, Optional

import numpy as np
from scipy import ndimage


SUMMARY_KEYS = (
    "height_before_step_m", "lowest_height_m", "p2_drop_stop_pa", "time_stuck_bottom_s",
    "p2_breakaway_pa", "time_return_after_step_s", "p2_after_climb_pa",
    "highest_height_m", "p2_jump_pa", "time_stuck_top_s", "p2_start_down_pa",
    "time_return_after_removal_s",
)


@dataclasses.dataclass
class EventOptions:
    """Tuning of the event extraction. Defaults suit 1..100 Hz logs. The band
    defaults to the built-in config's, as the C loader gives it (leveler.config)."""
    band_lower_m: Optional[float] = None
    band_upper_m: Optional[float] = None
    step_min_n: float = 100.0        # smaller load changes are not events (200 lb = 890 N)
    smooth_s: float = 0.2            # moving-median window
    rest_tol_min_m: float = 0.25e-3  # about the thesis's 0.01 in resolution
    before_s: float = 1.0            # window for the height before the step
    settle_s: float = 1.0            # window for the settled pressure after the climb
    fit_s: float = 0.5               # line fit for the pressure at a corner


@dataclasses.dataclass
class LoadEvent:
    index: int          # first sample of the change
    t_s: float
    before_n: float
    after_n: float

    @property
    def delta_n(self):
        return self.after_n - self.before_n


@dataclasses.dataclass
class Excursion:
    """One drop (after a load step) or jump (after a removal)."""
    event: LoadEvent
    direction: int                          # -1 drop, +1 jump
    t_extreme_s: float                      # first time the extreme is reached
    extreme_m: float                        # smoothed extreme height
    level_m: Optional[float] = None         # resting level (median raw height)
    t_rest_s: Optional[float] = None
    t_leave_s: Optional[float] = None       # break-away / start down
    t_return_s: Optional[float] = None      # back at the band edge
    p2_rest_pa: Optional[float] = None
    p2_leave_pa: Optional[float] = None     # max (drop) / min (jump) while resting
    p2_settled_pa: Optional[float] = None
    tolerance_m: float = 0.0


@dataclasses.dataclass
class Analysis:
    """Everything the extraction found; ``summary()`` gives the JSON dict."""
    load_events: List[LoadEvent]
    step: Optional[Excursion]
    removal: Optional[Excursion]
    height_before_step_m: Optional[float]
    noise_sigma_m: float
    quantum_m: float
    options: EventOptions

    def summary(self):
        s = dict.fromkeys(SUMMARY_KEYS)
        s["height_before_step_m"] = self.height_before_step_m
        if self.step is not None:
            e = self.step
            s["lowest_height_m"] = e.level_m
            s["p2_drop_stop_pa"] = e.p2_rest_pa
            s["time_stuck_bottom_s"] = _diff(e.t_leave_s, e.t_rest_s)
            s["p2_breakaway_pa"] = e.p2_leave_pa
            s["time_return_after_step_s"] = _diff(e.t_return_s, e.event.t_s)
            s["p2_after_climb_pa"] = e.p2_settled_pa
        if self.removal is not None:
            e = self.removal
            s["highest_height_m"] = e.level_m
            s["p2_jump_pa"] = e.p2_rest_pa
            s["time_stuck_top_s"] = _diff(e.t_leave_s, e.t_rest_s)
            s["p2_start_down_pa"] = e.p2_leave_pa
            s["time_return_after_removal_s"] = _diff(e.t_return_s, e.event.t_s)
        return {k: _clean(v) for k, v in s.items()}


def _diff(a, b):
    return None if a is None or b is None else a - b


def _clean(v):
    if v is None:
        return None
    v = float(v)
    return v if math.isfinite(v) else None


# --- building blocks ---------------------------------------------------------------

def find_load_events(t_s, load_n, step_min_n=100.0):
    """Load changes larger than ``step_min_n`` (see module doc)."""
    t = np.asarray(t_s, dtype=float)
    load = np.asarray(load_n, dtype=float)
    n = len(load)
    events: List[LoadEvent] = []
    if n == 0:
        return events
    eps = 0.05 * step_min_n
    ref = float(load[0])
    i = 1
    while i < n:
        if abs(load[i] - ref) > step_min_n:
            start = i
            while start > 1 and abs(load[start - 1] - ref) > eps:
                start -= 1
            end = i
            while end + 1 < n and abs(load[end + 1] - load[end]) > eps:
                end += 1
            new = float(load[end])
            events.append(LoadEvent(start, float(t[start]), ref, new))
            ref = new
            i = end + 1
        else:
            i += 1
    return events


def _window_samples(t, seconds):
    if len(t) < 2:
        return 1
    dt = float(np.median(np.diff(t)))
    w = int(round(seconds / dt)) if dt > 0 else 1
    w = max(w, 1)
    return w if w % 2 == 1 else w + 1


def moving_median(values, window):
    """Centred moving median over ``window`` samples (odd); NaNs ignored,
    edges use the nearest sample."""
    v = np.asarray(values, dtype=float)
    if window <= 1 or len(v) == 0:
        return v.copy()
    if not np.isnan(v).any():
        return ndimage.median_filter(v, size=window, mode="nearest")
    if np.isnan(v).all():
        return v.copy()
    half = window // 2
    padded = np.concatenate([np.full(half, v[0]), v, np.full(half, v[-1])])
    windows = np.lib.stride_tricks.sliding_window_view(padded, window)
    with np.errstate(all="ignore"):
        import warnings
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            return np.nanmedian(windows, axis=1)


def noise_and_quantum(values):
    """(sigma, quantum) of a signal that is mostly still or ramping: sigma
    from the median absolute second difference, quantum the smallest non-zero
    first difference."""
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if len(v) < 3:
        return 0.0, 0.0
    d = np.abs(np.diff(v))
    # Second differences vanish on straight ramps as on flats, so motion and
    # steady pressure changes do not count as noise; var(d2) = 6 sigma^2.
    d2 = np.abs(np.diff(v, 2))
    sigma = 1.4826 * float(np.median(d2)) / math.sqrt(6.0)
    if sigma < 1e-9 * max(float(np.max(np.abs(v))), 1.0):
        sigma = 0.0             # rounding of the printed numbers, not noise
    nz = d[d > 1e-12]
    quantum = float(nz.min()) if nz.size else 0.0
    return sigma, quantum


def _crossing(t, y, i, level):
    """Time at which y crosses ``level`` between samples i-1 and i."""
    if i <= 0:
        return float(t[0])
    y0, y1 = y[i - 1], y[i]
    if y1 == y0:
        return float(t[i])
    f = (level - y0) / (y1 - y0)
    f = min(max(f, 0.0), 1.0)
    return float(t[i - 1] + f * (t[i] - t[i - 1]))


def _extend(dt_per_tol, tol, distance):
    """Time to cover ``distance`` at the speed tol / dt_per_tol, clamped to
    [0, dt_per_tol] (never more than one more tolerance step)."""
    if tol <= 0 or dt_per_tol <= 0:
        return 0.0
    return min(max(distance / tol * dt_per_tol, 0.0), dt_per_tol)


def _line_value(t, y, t0, t1, when):
    """Value at ``when`` of the least-squares line through the finite samples
    of y in [t0, t1]; falls back to interpolation with fewer than 3 samples."""
    inside = (t >= t0) & (t <= t1) & np.isfinite(y)
    if np.count_nonzero(inside) < 3:
        return _value_at(t, y, when)
    tc, yc = t[inside] - when, y[inside]
    slope, intercept = np.polyfit(tc, yc, 1)
    # One pass of outlier rejection, so a spike does not tilt the line.
    resid = yc - (slope * tc + intercept)
    mad = 1.4826 * float(np.median(np.abs(resid)))
    keep = np.abs(resid) <= max(5.0 * mad, 1e-9 * max(float(np.max(np.abs(yc))), 1.0))
    if 3 <= np.count_nonzero(keep) < len(yc):
        slope, intercept = np.polyfit(tc[keep], yc[keep], 1)
    return _clean(intercept)


def _value_at(t, y, when):
    if when is None or not np.isfinite(y).any():
        return None
    ok = np.isfinite(y)
    return _clean(np.interp(when, t[ok], y[ok]))


def _excursion(t, h_raw, h_s, p2_raw, event, window_end, direction, tol, opts):
    """Drop (direction -1) or jump (+1) after ``event`` within [event, window_end)."""
    lo, hi = event.index, window_end
    if hi - lo < 2:
        return None
    seg = h_s[lo:hi]
    # Mirror a jump into a drop so one code path serves both.
    sgn = -direction
    y = sgn * seg                     # the extreme is the minimum of y
    k_ext = int(np.argmin(y))
    y_ext = float(y[k_ext])
    edge = opts.band_lower_m if direction < 0 else opts.band_upper_m
    edge_y = sgn * edge
    ex = Excursion(event=event, direction=direction, t_extreme_s=float(t[lo + k_ext]),
                   extreme_m=float(seg[k_ext]), tolerance_m=tol)

    # Return into the band after the extreme.
    k_ret = None
    after = np.flatnonzero(y[k_ext:] >= edge_y)
    if y_ext < edge_y and after.size:
        k_ret = k_ext + int(after[0])
        ex.t_return_s = _crossing(t[lo:hi], y, k_ret, edge_y)
    search_end = k_ret if k_ret is not None else len(y)

    # At the extreme. Pass 1: within the tolerance of the smoothed extreme
    # gives the resting samples and their level (median of the raw heights).
    # Pass 2: the same around that level, which noise does not bias.
    tt = t[lo:hi]
    near = np.flatnonzero(y[:search_end] <= y_ext + tol)
    if not near.size:                 # NaN heights (a failed simulation): no resting level
        return None
    rest = slice(lo + int(near[0]), lo + int(near[-1]) + 1)
    ex.level_m = _clean(np.median(h_raw[rest]))
    y_ref = max(sgn * ex.level_m, y_ext)
    near = np.flatnonzero(y[:search_end] <= y_ref + tol)
    k_rest, k_leave = int(near[0]), int(near[-1])
    still_there = k_leave >= len(y) - 1
    ex.t_rest_s = _crossing(tt, y, k_rest, y_ref + tol) if k_rest > 0 else float(tt[0])
    # Corner refinement: extend the motion just outside the tolerance (between
    # 2*tol and tol from the level) in a straight line to the level, so the
    # tolerance itself does not shorten the rest.
    far = np.flatnonzero(y[:k_rest] > y_ref + 2 * tol)
    if k_rest > 0 and far.size:
        t0 = _crossing(tt, y, int(far[-1]) + 1, y_ref + 2 * tol)
        ex.t_rest_s += _extend(ex.t_rest_s - t0, tol, tol)
    if not still_there:
        ex.t_leave_s = _crossing(tt, y, k_leave + 1, y_ref + tol)
        far = np.flatnonzero(y[k_leave + 1:search_end] >= y_ref + 2 * tol)
        if far.size:
            t2 = _crossing(tt, y, k_leave + 1 + int(far[0]), y_ref + 2 * tol)
            ex.t_leave_s -= _extend(t2 - ex.t_leave_s, tol, tol)
            ex.t_leave_s = max(ex.t_leave_s, ex.t_rest_s)
    # Pressures at the two corners: a straight line through the (despiked)
    # pressure on the resting side of the corner, evaluated at the corner. It
    # is exact on a clean log and, unlike a centred median, unbiased on a
    # noisy one where the pressure turns sharply.
    t_end_rest = ex.t_leave_s if ex.t_leave_s is not None else float(tt[-1])
    ex.p2_rest_pa = _line_value(t, p2_raw, ex.t_rest_s, min(ex.t_rest_s + opts.fit_s, t_end_rest),
                                ex.t_rest_s)
    if ex.t_leave_s is not None:
        ex.p2_leave_pa = _line_value(t, p2_raw, max(ex.t_leave_s - opts.fit_s, ex.t_rest_s),
                                     ex.t_leave_s, ex.t_leave_s)
    if ex.t_return_s is not None:
        t_end = float(t[hi - 1])
        settled = (t >= max(ex.t_return_s, t_end - opts.settle_s)) & (t <= t_end)
        settled[:lo] = False
        p = p2_raw[settled]
        p = p[np.isfinite(p)]
        if p.size:
            ex.p2_settled_pa = float(np.median(p))
    return ex


def analyze(log, options: Optional[EventOptions] = None) -> Analysis:
    """Finds the load events and the figures of the first step and removal."""
    opts = options or EventOptions()
    if opts.band_lower_m is None or opts.band_upper_m is None:
        from . import config
        built_in = config.default_config()
        opts = dataclasses.replace(opts, band_lower_m=opts.band_lower_m if opts.band_lower_m is not None
                                   else built_in.band_lower_m,
                                   band_upper_m=opts.band_upper_m if opts.band_upper_m is not None
                                   else built_in.band_upper_m)
    t = np.asarray(log.t_s, dtype=float)
    h = np.asarray(log.height_m, dtype=float)
    p2 = np.asarray(log.p_spring_pa, dtype=float)
    w = _window_samples(t, opts.smooth_s)
    sigma, quantum = noise_and_quantum(h)
    # A noiseless signal (a simulator's) is left as it is: a median would clip
    # its pressure peaks slightly.
    # The height is smoothed: a median keeps plateaus, ramps and their corners
    # exactly and removes spikes. The pressure figures come from robust
    # straight-line fits to the raw pressure instead.
    h_s = moving_median(h, w)
    sigma_s = sigma * 1.2533 / math.sqrt(w)     # median of w samples: sigma*sqrt(pi/2)/sqrt(w)
    tol = max(opts.rest_tol_min_m, 5.0 * sigma_s, 1.5 * quantum)

    events = find_load_events(t, log.load_n, opts.step_min_n)
    step_i = next((i for i, e in enumerate(events) if e.delta_n > 0), None)
    removal_i = None
    if step_i is not None:
        removal_i = next((i for i in range(step_i + 1, len(events)) if events[i].delta_n < 0), None)

    def window_end(i):
        return events[i + 1].index if i + 1 < len(events) else len(t)

    step = removal = None
    before = None
    if step_i is not None:
        e = events[step_i]
        pre = (t >= e.t_s - opts.before_s) & (t < e.t_s)
        if pre.any():
            before = float(np.median(h[pre]))
        step = _excursion(t, h, h_s, p2, e, window_end(step_i), -1, tol, opts)
    if removal_i is not None:
        removal = _excursion(t, h, h_s, p2, events[removal_i], window_end(removal_i),
                             +1, tol, opts)
    return Analysis(events, step, removal, before, sigma, quantum, opts)


def summarize(log, options: Optional[EventOptions] = None):
    """The flat JSON dict (``SUMMARY_KEYS``, SI, None where not defined)."""
    return analyze(log, options).summary()

"""Split a run into the phases of the thesis experiment.

steady      before the first load change
drop        after a load increase, until the platform stops falling
stuck_low   resting at the bottom while the spring charges
climb       rising back to the band
settle      back in the band, until the next load change
jump        after a load decrease, until the platform stops rising
stuck_high  resting at the top while the spring discharges
return      falling back to the band

The split is made on the REAL run (the reference) and applied to the
simulated traces on the same time base.
"""
import numpy as np
from scipy.ndimage import median_filter

PHASES = ("steady", "drop", "stuck_low", "climb", "settle", "jump", "stuck_high", "return")
LOAD_STEP_N = 50.0       # smaller load changes are noise, not a schedule step


def load_steps(t_s, load_n):
    """Indices where the load schedule changes by more than LOAD_STEP_N."""
    d = np.diff(load_n)
    return [int(i) + 1 for i in np.flatnonzero(np.abs(d) > LOAD_STEP_N)]


def split(t_s, height_m, load_n, tol_m=None):
    """Return an array of phase labels (strings), one per sample."""
    n = len(t_s)
    dt = float(np.median(np.diff(t_s)))
    win = max(1, int(round(0.2 / dt)) | 1)
    h = median_filter(np.nan_to_num(height_m, nan=np.nanmedian(height_m)), size=win, mode="nearest")
    if tol_m is None:
        noise = np.std(height_m - h) if n > win else 0.0
        tol_m = max(0.6e-3, 4.0 * noise)
    labels = np.array(["steady"] * n, dtype=object)
    steps = load_steps(t_s, load_n)
    edges = steps + [n]
    for k, i0 in enumerate(steps):
        i1 = edges[k + 1]
        seg = h[i0:i1]
        if len(seg) < 3:
            labels[i0:i1] = "settle"
            continue
        before = h[max(0, i0 - win):i0].mean() if i0 > 0 else seg[0]
        up = load_n[i0] > load_n[i0 - 1]          # load increase: platform drops
        s = seg if up else -seg
        b = before if up else -before
        j_ext = int(np.argmin(s))                 # bottom (or top)
        ext = s[j_ext]
        if b - ext < 2 * tol_m:                   # the platform hardly moved
            labels[i0:i1] = "settle"
            continue
        near = np.flatnonzero(s[: ] <= ext + tol_m)
        j_stop = int(near[0])                     # stops falling
        # stuck: contiguous samples near the extreme after j_stop
        j_leave = j_stop
        while j_leave + 1 < len(s) and s[j_leave + 1] <= ext + tol_m:
            j_leave += 1
        # back: at the level before the step, or at rest again somewhere in the band
        # (the controller stops anywhere inside it) after moving off the extreme
        ahead = max(1, int(round(0.5 / dt)))
        s_ahead = np.concatenate([s[ahead:], np.full(ahead, s[-1])])
        resting = np.abs(s_ahead - s) < 0.5 * tol_m
        done = (s >= b - tol_m) | (resting & (s - ext > 2.0 * tol_m))
        back = np.flatnonzero(done[j_leave:])
        j_back = j_leave + int(back[0]) if back.size else len(s)
        names = ("drop", "stuck_low", "climb") if up else ("jump", "stuck_high", "return")
        labels[i0:i0 + j_stop] = names[0]
        labels[i0 + j_stop:i0 + j_leave + 1] = names[1]
        labels[i0 + j_leave + 1:i0 + j_back] = names[2]
        labels[i0 + j_back:i1] = "settle"
    return labels


def spans(t_s, labels):
    """[(phase, t_start, t_end)] of contiguous spans, in time order."""
    out = []
    start = 0
    for i in range(1, len(labels) + 1):
        if i == len(labels) or labels[i] != labels[start]:
            out.append((labels[start], float(t_s[start]), float(t_s[i - 1])))
            start = i
    return out

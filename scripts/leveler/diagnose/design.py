"""Experiment design for look-alikes: which runnable test separates two fitted
candidates best?

Each test schedule is a load schedule (the file format of `leveler-sim
--schedule`, docs/config-format.md, which the rig runs the same way): the
firmware in the loop decides, both fitted candidates are simulated from the
state the logs start in, and the schedules are ranked by the predicted
difference of the measured signals in units of the logs' own sensor noise
(RMS over the run of the per-sample difference / noise, summed over signals).
"""
import os

import numpy as np

from .model import CLOSED_LOOP
from .runs import Run

LB = 4.4482216152605
TICK_S = 0.01
SIGNAL_FLOOR = {"height_m": 2e-5, "p_spring_pa": 50.0, "p_pipe_pa": 50.0, "p_acc_pa": 50.0}


def noise_levels(runs):
    """Sensor noise per signal from the logs: the spread of sample-to-sample
    differences (median absolute deviation, robust to steps), over sqrt(2)."""
    out = {}
    for s, floor in SIGNAL_FLOOR.items():
        d = np.concatenate([np.diff(r.signals[s]) for r in runs if r.measured(s)] or [np.zeros(0)])
        d = d[np.isfinite(d)]
        if d.size:
            out[s] = max(1.4826 * float(np.median(np.abs(d - np.median(d)))) / np.sqrt(2.0), floor)
    return out


def candidate_schedules(base_n):
    """Runnable load schedules around the logs' base load: (name, [(t_s, load_n)], end_s)."""
    out = []
    for lb in (100, 200, 300):
        out.append((f"step +{lb} lb for 25 s", [(0.0, base_n), (5.0, base_n + lb * LB), (30.0, base_n)], 45.0))
    out.append(("step +200 lb for 6 s", [(0.0, base_n), (5.0, base_n + 200 * LB), (11.0, base_n)], 30.0))
    out.append(("staircase +100, +200, +300 lb", [(0.0, base_n), (5.0, base_n + 100 * LB),
                                                  (15.0, base_n + 200 * LB), (25.0, base_n + 300 * LB),
                                                  (40.0, base_n)], 55.0))
    out.append(("relief -150 lb for 20 s", [(0.0, base_n), (5.0, base_n - 150 * LB), (25.0, base_n)], 40.0))
    out.append(("pulses +250 lb, 3 s every 10 s", [(0.0, base_n)] + [
        (t, base_n + (250 * LB if k % 2 == 0 else 0.0))
        for k, t in enumerate((5.0, 8.0, 15.0, 18.0, 25.0, 28.0))], 40.0))
    return out


def schedule_loads(t, steps):
    """The load over each tick from t[i] of a schedule [(t_s, load_n)]: the last step
    at or before t[i], with half a tick of slack (the simulator's rule, stepper.h)."""
    load = np.full(len(t), steps[0][1])
    for t0, v in steps:
        load[t >= t0 - TICK_S / 2] = v
    return load


def schedule_run(like, steps, end_s):
    """A closed-loop run of the schedule, starting in the state `like` starts in."""
    t = np.round(np.arange(0.0, end_s + TICK_S / 2, TICK_S), 2)
    load = schedule_loads(t, steps)
    n0 = max(1, int(np.searchsorted(like.t_s, like.t_s[0] + 0.5)))
    sig = {}
    for s, v in like.signals.items():
        v0 = v[:n0][np.isfinite(v[:n0])]
        sig[s] = np.full(len(t), float(np.mean(v0)) if v0.size else np.nan)
    return Run(path="design.csv", t_s=t, signals=sig, load_n=load, commands={})


def separation(problem, run, a, b, noise):
    """Predicted difference between fitted candidates a and b, in noise units."""
    ta = problem.sim.simulate(problem.config, run, a[0], a[1], CLOSED_LOOP)
    tb = problem.sim.simulate(problem.config, run, b[0], b[1], CLOSED_LOOP)
    total = 0.0
    for s, sd in noise.items():
        d = (ta.signals[s] - tb.signals[s]) / sd
        d = d[np.isfinite(d)]
        if d.size:
            total += float(np.mean(d * d))
    return float(np.sqrt(total))


def propose(problem, a, b, noise=None):
    """Rank the schedules for separating a = (effect, params) from b; best first."""
    noise = noise or noise_levels(problem.runs)
    like = problem.runs[0]
    base = float(like.load_n[0])
    ranked = []
    for name, steps, end in candidate_schedules(base):
        run = schedule_run(like, steps, end)
        ranked.append({"schedule": name, "steps": [[float(t), float(v)] for t, v in steps] + [[end, base]],
                       "separation_noise_units": separation(problem, run, a, b, noise)})
    ranked.sort(key=lambda r: -r["separation_noise_units"])
    return {"between": [a[0], b[0]], "noise": noise, "ranked": ranked}


def write_schedule(path, proposal):
    """The best schedule as a `leveler-sim --schedule` file (t_s,load_n)."""
    best = proposal["ranked"][0]
    tmp = path + ".tmp"
    with open(tmp, "w") as fh:
        fh.write(f"# proposed by leveler-diagnose to tell {proposal['between'][0]} from "
                 f"{proposal['between'][1]}: {best['schedule']}\n")
        fh.write(f"# predicted difference {best['separation_noise_units']:.1f} x the sensor noise\n")
        fh.write("t_s,load_n\n")
        for t, v in best["steps"]:
            fh.write(f"{t:g},{v:.1f}\n")
    os.replace(tmp, path)

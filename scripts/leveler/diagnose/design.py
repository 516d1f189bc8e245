"""Experiment design for look-alikes: which runnable test separates two fitted
candidates best?

Each test schedule is a schedule file of `leveler-sim --schedule`
(docs/config-format.md): load steps, or manual actuator sequences written
through the register map (mode, manual_* requests) at constant load. The rig
runs the same file (leveler-schedule-run). The firmware in the loop decides
(or, in manual mode, passes the requests through its supervisor), both fitted
candidates are simulated from the state the logs start in, and the schedules
are ranked by the predicted difference of the measured signals in units of
the logs' own sensor noise (RMS over the run of the per-sample difference /
noise, summed over signals).
"""
import json
import os
from dataclasses import replace

import numpy as np

from leveler import paths

from leveler.engine import schedule_apply, schedule_columns, tick_grid

from .cplant import request_commands
from .model import CLOSED_LOOP
from .runs import Run

LB = 4.4482216152605
SIGNAL_FLOOR = {"height_m": 2e-5, "p_spring_pa": 50.0, "p_pipe_pa": 50.0, "p_acc_pa": 50.0}


def noise_levels(runs):
    """Sensor noise per signal from the logs: the spread of sample-to-sample
    differences (median absolute deviation, robust to steps), over sqrt(2); never
    less than the rounding error of the log's resolution (its smallest step q: a
    reading rounded to q is off by q/sqrt(12) RMS whatever the model). Without
    that bound, a converter's counts that repeat in over half the samples gave a
    median deviation of nothing and the floor, 28 times under the estimate of a
    log one repeat fewer (1.41 kPa against 50 Pa on 1.35 kPa counts)."""
    out = {}
    for s, floor in SIGNAL_FLOOR.items():
        d = np.concatenate([np.diff(r.signals[s]) for r in runs if r.measured(s)] or [np.zeros(0)])
        d = d[np.isfinite(d)]
        if d.size:
            steps = np.abs(d[d != 0.0])
            rounding = float(steps.min()) / np.sqrt(12.0) if steps.size else 0.0
            out[s] = max(1.4826 * float(np.median(np.abs(d - np.median(d)))) / np.sqrt(2.0), rounding, floor)
    return out


def load_schedules(base_n):
    """Runnable load schedules around the logs' base load: (name, [(t_s, load_n, {})], end_s)."""
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
    return [(name, [(t, v, {}) for t, v in steps], end) for name, steps, end in out]


MODE = "mode"   # the schedule column (register) of the mode


def _mode_values():
    """The mode register's values by name, from the register map's one source."""
    with open(paths.data("firmware/regmap/registers.json", "registers.json")) as fh:
        return next(r for r in json.load(fh)["registers"] if r["name"] == MODE)["enum"]


_MODES = _mode_values()
AUTO, MANUAL = _MODES["auto"], _MODES["manual"]


def requests_off():
    """Every manual request cleared: {register: 0} over the C table of schedule columns."""
    return {c: 0 for c in request_commands()}


def _manual(name, base_n, moves, back_s, end_s):
    """A manual actuator sequence at constant load: at 5 s the rig goes to manual
    with everything off, `moves` [(t_s, {request: 0/1})] follow, at back_s every
    request is cleared and the mode returns to auto (the controller brings the
    platform back into its band), the run ends at end_s."""
    off = requests_off()
    rows = [(0.0, base_n, {}), (5.0, base_n, dict(off, **{MODE: MANUAL}))]
    rows += [(t, base_n, dict(w)) for t, w in moves]
    rows += [(back_s, base_n, dict(off, **{MODE: AUTO})), (end_s, base_n, {})]
    return name, rows, end_s


def manual_schedules(base_n, accumulator=False):
    """Runnable manual actuator sequences through the register map (mode 2, the
    manual requests; the supervisor still watches them): short on-times that
    separate what the load steps cannot, e.g. a valve's opening dynamics from a
    line's delay (the compressor fills the pipe against the shut spring valve,
    then the valve pulses: the spring's pressure answers each pulse at once
    through a slow valve, late through a long line), a line's transport delay
    from a tube's lag (compressor runs against the shut spring valve: P1
    alone answers, the valves play no part), a sensor's lag from friction
    (vent pulses too short to move the platform still move P2), the pipe's own
    volume and delay (the compressor starting into an open valve).
    Compressor runs stay a few seconds (the supervisor's run-time limit is
    minutes), pressures stay far below its overpressure limits, and every
    sequence ends back in auto. With an accumulator its valve is pulsed too."""
    c1, c0 = {"manual_compressor": 1}, {"manual_compressor": 0}
    v1, v0 = {"manual_spring_valve": 1}, {"manual_spring_valve": 0}
    out = []
    for on_s in (0.2, 0.5):
        moves = [(5.5, c1)]
        for k in range(4):
            t = 7.5 + 1.5 * k
            moves += [(t, v1), (round(t + on_s, 2), v0)]
        out.append(_manual(f"compressor on, spring valve pulsed 4 x {on_s:g} s", base_n, moves, 13.5, 30.0))
    # the motor needs seconds to spin up (J/D about 2.5 s): compressor runs last seconds
    out.append(_manual("compressor 2 x 3 s against the shut spring valve", base_n,
                       [(5.5, c1), (8.5, c0), (11.5, c1), (14.5, c0)], 17.5, 35.0))
    out.append(_manual("compressor 2 s against the shut spring valve, then the valve open 2 s", base_n,
                       [(5.5, c1), (7.5, v1), (9.5, dict(c0, **v0))], 11.0, 30.0))
    out.append(_manual("compressor started into the open spring valve for 2 s", base_n,
                       [(5.5, v1), (6.0, c1), (8.0, c0), (8.5, v0)], 10.0, 30.0))
    vent = []
    for k in range(3):
        t = 6.0 + 2.0 * k
        vent += [(t, {"manual_vent_valve": 1}), (t + 0.3, {"manual_vent_valve": 0})]
    out.append(_manual("vent pulsed 3 x 0.3 s", base_n, vent, 12.0, 30.0))
    out.append(_manual("vent pulsed 3 x 0.3 s with the spring valve open", base_n,
                       [(5.5, v1)] + vent + [(11.0, v0)], 12.0, 30.0))
    if accumulator:
        acc = [(6.0 + 1.5 * k + d, {"manual_acc_valve": v}) for k in range(3) for d, v in ((0.0, 1), (0.3, 0))]
        out.append(_manual("accumulator valve pulsed 3 x 0.3 s into the open spring valve", base_n,
                           [(5.5, v1)] + acc + [(11.0, v0)], 12.0, 30.0))
    return out


def candidate_schedules(base_n, accumulator=False):
    """All runnable test schedules: (name, [(t_s, load_n, {register: value})], end_s)."""
    return load_schedules(base_n) + manual_schedules(base_n, accumulator)


def schedule_loads(t, steps):
    """The load over each tick from t[i] of a schedule [(t_s, load_n, ...)], by the
    simulator's own rule (stepper.h, asked through engine.schedule_apply)."""
    return schedule_apply(t, steps)[0]


def schedule_writes(steps):
    """The register writes of a schedule: [(t_s, {register: value})] for the rows that have any."""
    return [(float(row[0]), dict(row[2])) for row in steps if len(row) > 2 and row[2]]


def requested(t, steps):
    """The manual requests in force over each tick from t[i], -1 where the mode is not
    manual: {request: array of 0, 1 or -1}. Which rows are due when, and what the
    registers then hold, the C side says (the firmware's register map after the
    simulator's writes): the rule lives in the stepper alone."""
    regs = schedule_apply(t, steps)[1]
    manual = regs[MODE] == MANUAL
    return {k: np.where(manual, regs[k], -1) for k in request_commands()}


def schedule_run(like, steps, end_s):
    """A closed-loop run of the schedule, starting in the state `like` starts in."""
    t = tick_grid(end_s)
    load = schedule_loads(t, steps)
    n0 = max(1, int(np.searchsorted(like.t_s, like.t_s[0] + 0.5)))
    sig = {}
    for s, v in like.signals.items():
        v0 = v[:n0][np.isfinite(v[:n0])]
        sig[s] = np.full(len(t), float(np.mean(v0)) if v0.size else np.nan)
    return Run(path="design.csv", t_s=t, signals=sig, load_n=load, commands={}, writes=schedule_writes(steps))


def overridden(trace, steps):
    """Ticks (after the first one following each write) where the simulated rig did not
    drive what the manual rows request: the supervisor stepped in (a limit), so the
    sequence is not safe to run as written."""
    req = requested(trace.t_s - trace.t_s[0], steps)
    bad = 0
    for k, want in req.items():
        drove = trace.commands.get(request_commands()[k])
        if drove is None:
            continue
        on = want >= 0
        on[1:] &= on[:-1]                     # a write takes effect at the next tick
        bad += int(np.sum(on & (np.asarray(drove) != want)))
    return bad


def distance(ta, tb, noise):
    """RMS over the run of the per-sample difference of two traces / the sensor noise,
    summed over the logged signals (noise units)."""
    total = 0.0
    for s, sd in noise.items():
        d = (ta.signals[s] - tb.signals[s]) / sd
        d = d[np.isfinite(d)]
        if d.size:
            total += float(np.mean(d * d))
    return float(np.sqrt(total))


def jittered(run, noise, sign):
    """The same planned run starting from a state differing by one standard deviation
    of the sensor noise in height and P2 (imperceptible in the logs it was read from)."""
    return replace(run, start_shift=(sign * noise.get("height_m", SIGNAL_FLOOR["height_m"]),
                                     sign * noise.get("p_spring_pa", SIGNAL_FLOOR["p_spring_pa"])))


def separation(problem, run, a, b, noise, steps=None, base=None):
    """Predicted difference between fitted candidates a and b, in noise units; the
    knife edge: how far either candidate's own prediction moves when the start
    moves by one standard deviation of the sensor noise (a platform held by
    hysteresis may break free a pulse earlier or later for no reason the rig
    can control); whether any simulation (a, b or base) saw the supervisor override the
    schedule's manual rows; and with base (the model without either effect): the
    smaller of a's and b's differences from it beyond their knife edges, else None."""
    # a candidate is (effect, params) on the problem's config, or (effect, params, config, label)
    sim = lambda r, e: problem.sim.simulate(e[2] if len(e) > 2 else problem.config, r, e[0], e[1], CLOSED_LOOP)
    models = [a, b] + ([base] if base is not None else [])
    traces = [sim(run, m) for m in models]
    edges = [0.0] * len(models)
    for sign in (-1.0, 1.0):
        r = jittered(run, noise, sign)
        for i, m in enumerate(models):
            edges[i] = max(edges[i], distance(traces[i], sim(r, m), noise))
    # the base is the rig as it may well be (neither effect): its run must be safe too
    unsafe = bool(steps) and sum(overridden(tr, steps) for tr in traces) > 0
    shows = None
    if base is not None:
        shows = min(max(distance(traces[i], traces[2], noise) - max(edges[i], edges[2]), 0.0) for i in (0, 1))
    return distance(traces[0], traces[1], noise), max(edges[0], edges[1]), unsafe, shows


def propose(problem, a, b, noise=None, base=None):
    """Rank the schedules for separating a = (effect, params) from b (or either as
    (effect or None, params, config, label): a model with another config, such as the
    calibrated one against an effect on the config as given); best first, by
    the predicted difference beyond the knife edge (a difference that an
    imperceptible change of the start also makes is no evidence). With base (the
    model without either effect, as a or b's 4-tuple): by the smaller of that
    and how far each of a and b lies from base beyond the knife edge. The run
    joins the held-out ones, where an effect must still show against no effect:
    a schedule that parts a from b but on which the true one barely shows dilutes
    its evidence (present family seed 30, 1000 lb accumulator rig: area against
    line_delay parted by 11.4 noise units on a spring-valve pulse train, and the
    run then left area below what the held-out runs could confirm). A manual
    sequence the supervisor would override (in either candidate's simulation,
    or the base's: the rig may have neither effect) is left out of the ranking
    and listed under `unsafe`."""
    noise = noise or noise_levels(problem.runs)
    like = problem.runs[0]
    base_n = float(like.load_n[0])
    ranked, unsafe = [], []
    for name, steps, end in candidate_schedules(base_n, like.measured("p_acc_pa")):
        run = schedule_run(like, steps, end)
        sep, edge, over, shows = separation(problem, run, a, b, noise, steps, base)
        rows = [[float(r[0]), float(r[1]), dict(r[2])] for r in steps]
        if rows[-1][0] < end:
            rows.append([end, base_n, {}])
        entry = {"schedule": name, "kind": "manual" if schedule_writes(steps) else "load", "steps": rows,
                 "separation_noise_units": max(sep - edge, 0.0), "difference_noise_units": sep,
                 "knife_edge_noise_units": edge}
        if shows is not None:
            entry["each_shows_noise_units"] = shows
        (unsafe if over else ranked).append(entry)
    score = lambda r: min(r["separation_noise_units"], r.get("each_shows_noise_units", np.inf))
    ranked.sort(key=lambda r: (-score(r), -r["separation_noise_units"], -r["difference_noise_units"]))
    label = lambda e: e[3] if len(e) > 3 else e[0]
    return {"between": [label(a), label(b)], "noise": noise, "ranked": ranked,
            "unsafe": [u["schedule"] for u in unsafe]}


def write_schedule(path, proposal, columns=None):
    """The best schedule as a `leveler-sim --schedule` file: t_s,load_n and, for a
    manual sequence, the register columns it writes (empty cell = no write)."""
    best = proposal["ranked"][0]
    order = columns or schedule_columns()
    used = [c for c in order if any(c in row[2] for row in best["steps"] if len(row) > 2)]
    tmp = path + ".tmp"
    with open(tmp, "w") as fh:
        fh.write(f"# proposed by leveler-diagnose to tell {proposal['between'][0]} from "
                 f"{proposal['between'][1]}: {best['schedule']}\n")
        fh.write(f"# predicted difference {best.get('difference_noise_units', best['separation_noise_units']):.1f} "
                 f"x the sensor noise, {best['separation_noise_units']:.1f} beyond the knife edge"
                 + (f"; each {best['each_shows_noise_units']:.1f} from no effect" if "each_shows_noise_units" in best
                    else "") + "\n")
        if used:
            fh.write(f"# {MODE} {MANUAL} = manual (the manual_* requests drive the actuators, still supervised), "
                     f"{AUTO} = auto; "
                     "load_n is weights on a real rig (leveler-schedule-run says when)\n")
        fh.write(",".join(["t_s", "load_n"] + used) + "\n")
        for row in best["steps"]:
            w = row[2] if len(row) > 2 else {}
            fh.write(",".join([f"{row[0]:g}", f"{row[1]:.1f}"] + [str(w[c]) if c in w else "" for c in used]) + "\n")
    os.replace(tmp, path)

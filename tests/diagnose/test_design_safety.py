"""The experiment design's safety check asks the C side which manual requests
are in force when (design.requested, engine.schedule_apply), and drops a
manual sequence the firmware's supervisor overrides. The expectations come
from the documented rules, not from the code under test: a row is due half a
tick early at the latest (stepper.h), and the supervisor latches its chatter
fault, outputs safe, on the switching that takes the count in the last minute
above chatter_max_per_min (90 by default: firmware/regmap/registers.json;
the thesis configs do not set it)."""
import numpy as np

from conftest import LB
from leveler.diagnose import design
from leveler.diagnose.model import CLOSED_LOOP
from leveler.diagnose.runs import Run

CONFIG = "thesis-900lb"
BASE_N = 900 * LB
CHATTER_MAX_PER_MIN = 90


def test_requests_follow_the_rows_by_the_half_tick_rule(cplant):
    t = np.round(np.arange(0.0, 3.0 + 0.005, 0.01), 2)
    steps = [(0.0, BASE_N, {}),
             (1.004, BASE_N, {"mode": design.MANUAL, "manual_compressor": 1}),   # due at the 1.00 s tick
             (1.506, BASE_N + 100.0, {"manual_compressor": 0, "manual_vent_valve": 1}),  # due at 1.51 s
             (2.0, BASE_N, {"mode": design.AUTO})]
    req, load = design.requested(t, steps), design.schedule_loads(t, steps)
    auto = (t < 1.0) | (t >= 2.0)
    assert all((v[auto] == -1).all() for v in req.values())     # requests count in manual mode only
    comp, vent = req["manual_compressor"], req["manual_vent_valve"]
    assert (comp[(t >= 1.0) & (t < 1.51)] == 1).all() and (comp[(t >= 1.51) & (t < 2.0)] == 0).all()
    assert (vent[(t >= 1.0) & (t < 1.51)] == 0).all() and (vent[(t >= 1.51) & (t < 2.0)] == 1).all()
    assert (req["manual_spring_valve"][~auto] == 0).all()       # never written: off since power-up
    assert (load[(t >= 1.51) & (t < 2.0)] == BASE_N + 100.0).all() and (load[t < 1.51] == BASE_N).all()


def vent_pulses(count, period_s=0.5, t0_s=6.0):
    """Manual mode at 5 s, the vent pulsed `count` times (half on, half off), back to auto."""
    rows = [(0.0, BASE_N, {}), (5.0, BASE_N, dict(design.requests_off(), mode=design.MANUAL))]
    for k in range(count):
        t = t0_s + period_s * k
        rows += [(t, BASE_N, {"manual_vent_valve": 1}), (t + period_s / 2, BASE_N, {"manual_vent_valve": 0})]
    back = t0_s + period_s * count + 1.0
    return rows + [(back, BASE_N, dict(design.requests_off(), mode=design.AUTO)), (back + 8.0, BASE_N, {})]


def closed_loop(cplant, steps):
    """The nominal plant from the config's state at rest, the firmware in the loop."""
    end = steps[-1][0]
    like = Run("like.csv", np.zeros(2), {s: np.full(2, np.nan) for s in design.SIGNAL_FLOOR}, np.full(2, BASE_N))
    run = design.schedule_run(like, steps, end)
    return cplant.simulate(CONFIG, run, None, {}, CLOSED_LOOP)


def test_a_sequence_the_supervisor_overrides_is_flagged_a_safe_one_is_not(cplant):
    safe = vent_pulses(10)                      # 20 switchings: far below the chatter limit
    assert design.overridden(closed_loop(cplant, safe), safe) == 0

    chatter = vent_pulses(50)                   # 100 switchings within 25 s
    tr = closed_loop(cplant, chatter)
    bad = design.overridden(tr, chatter)
    # switching 91 (the 46th opening, at 6 + 0.25 * 90 s) latches the fault: from then on the
    # outputs stay safe, so every requested opening left (5 of 0.25 s: 125 ticks) is not driven
    t_latch = 6.0 + 0.25 * (CHATTER_MAX_PER_MIN + 1 - 1)
    want = design.requested(tr.t_s, chatter)["manual_vent_valve"]
    first = tr.t_s[np.flatnonzero((want == 1) & (tr.commands["vent_valve"] != 1))[0]]
    assert abs(first - t_latch) < 0.015, first
    assert abs(bad - 125) <= 2, bad

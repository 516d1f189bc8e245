"""The C plant through ctypes: effects that are off change nothing, replay
reproduces the firmware-in-the-loop run, and the leak obeys eq. (8)/(9)."""
import numpy as np
import pytest

from conftest import LB, thesis_schedule
from leveler.diagnose import effects as fx
from leveler.diagnose.model import CLOSED_LOOP, REPLAY
from leveler.diagnose.runs import Run

CONFIG = "thesis-900lb"
PSI = 6894.757293168361
IN = 0.0254


def run_of(trace, load):
    return Run("mem.csv", trace.t_s, trace.signals, load, trace.commands)


@pytest.fixture(scope="module")
def closed(cplant):
    t, load = thesis_schedule()
    return cplant.generate(CONFIG, t, load, None, []), load


def test_closed_loop_nominal_is_the_thesis_run(closed):
    tr, _ = closed
    h_in = tr.signals["height_m"] / IN
    # Chapter III: 15.65 in before the step, 14.53 in lowest after +200 lb (published sim).
    assert abs(h_in[:400].mean() - 15.65) < 0.01
    assert abs(h_in[500:2000].min() - 14.53) < 0.1


def test_replay_reproduces_the_closed_loop_run(cplant, closed):
    tr, load = closed
    rep = cplant.simulate(CONFIG, run_of(tr, load), None, {}, REPLAY)
    assert np.max(np.abs(rep.signals["height_m"] - tr.signals["height_m"])) < 1e-9
    assert np.max(np.abs(rep.signals["p_spring_pa"] - tr.signals["p_spring_pa"])) < 1e-3


@pytest.mark.parametrize("name", fx.NAMES)
def test_effect_switched_off_is_the_nominal_plant(cplant, closed, name):
    tr, load = closed
    run = run_of(tr, load)
    base = cplant.simulate(CONFIG, run, None, {}, REPLAY)
    off = cplant.simulate(CONFIG, run, name, fx.get(name).nominal(), REPLAY)
    for s in ("height_m", "p_spring_pa", "p_pipe_pa"):
        assert np.array_equal(base.signals[s], off.signals[s]), s


@pytest.mark.parametrize("name", fx.NAMES)
def test_each_candidate_moves_the_trace(cplant, closed, name):
    tr, load = closed
    run = run_of(tr, load)
    e = fx.get(name)
    # three quarters up each range (the middle of a symmetric range is "off")
    mid = {p.name: (p.lo ** 0.25 * p.hi ** 0.75 if p.log else 0.25 * p.lo + 0.75 * p.hi) for p in e.params}
    on = cplant.simulate(CONFIG, run, name, mid, REPLAY)
    assert np.all(np.isfinite(on.signals["height_m"]))
    d = np.abs(on.signals["p_spring_pa"] - tr.signals["p_spring_pa"]).max()
    assert d > 100.0, f"{name} at mid-range changed P2 by only {d:.1f} Pa"


def closed_valves_run(seconds=5.0):
    t = np.round(np.arange(0.0, seconds + 1e-9, 0.01), 2)
    load = np.full(len(t), 900.0 * LB)
    zeros = {c: np.zeros(len(t), dtype=np.int32) for c in ("compressor", "spring_valve", "vent_valve", "acc_valve")}
    sig = {"height_m": np.full(len(t), 15.65 * IN), "p_spring_pa": np.full(len(t), 89.0 * PSI),
           "p_pipe_pa": np.full(len(t), 89.0 * PSI), "p_acc_pa": np.full(len(t), np.nan)}
    return Run("closed.csv", t, sig, load, zeros)


def test_mass_is_conserved_with_valves_shut_and_the_leak_follows_eq_8(cplant):
    run = closed_valves_run()
    nom = cplant.simulate(CONFIG, run, None, {}, REPLAY)
    p2 = nom.signals["p_spring_pa"]
    assert np.ptp(p2) < 1e-6 * p2[0]               # nothing flows: P2 stays put
    area = 1e-8
    leak = cplant.simulate(CONFIG, run, "leak", {"leak_area_m2": area}, REPLAY)
    p = leak.signals["p_spring_pa"]
    # Independent expectation: choked flow (P2/Pa < 0.528) m = A P sqrt(k/(R T)) (2/(k+1))^((k+1)/(2(k-1)))
    # through dP2/dt = Z n R T m / V2 with the thesis values (R T in SI, V2 = 270 in^3).
    k, temp, z, n = 1.4, 535 / 1.8, 0.95, 1.1
    r = 640.08 * 4.4482216152605 * 0.0254 / 0.45359237 / (5.0 / 9.0)      # in lbf/(lbm R) -> J/(kg K)
    m = area * p[0] * np.sqrt(k / (r * temp)) * (2 / (k + 1)) ** ((k + 1) / (2 * (k - 1)))
    expect = z * n * r * temp * m / (270 * IN ** 3)
    slope = (p[10] - p[0]) / (run.t_s[10] - run.t_s[0])
    assert slope < 0
    assert abs(-slope - expect) / expect < 0.02


def test_closed_loop_on_an_irregular_rig_time_base(cplant, closed):
    """A rig log's times jitter and need not start at 0: the firmware still ticks
    every 10 ms and the trace is read back at the log's times."""
    tr, load = closed
    rng = np.random.default_rng(0)
    t = 100.0 + np.cumsum(rng.uniform(0.008, 0.012, 5000))
    step = np.interp(t - t[0], tr.t_s, load)
    rig = Run("rig.csv", t, {k: np.full(len(t), np.nan) for k in tr.signals}, np.where(step > 4500, 4893.0, 4003.4))
    out = cplant.simulate(CONFIG, rig, None, {}, CLOSED_LOOP)
    assert len(out.signals["height_m"]) == len(t)
    h_in = out.signals["height_m"] / IN
    assert abs(h_in[: int(4.0 / 0.01)].mean() - 15.65) < 0.01
    assert abs(h_in.min() - 14.53) < 0.1       # the same drop as on the regular grid

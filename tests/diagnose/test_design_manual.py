"""Issue 12's experiment design with manual actuator sequences, end to end on
the C plant: two candidates whose load-step predictions differ little, a
proposed manual sequence that separates them, written as a schedule file,
read back by the simulator's parser and run through the firmware's register
map on the blind test's truth (libleveler_truth.so, a different functional
form: a pipe split in two behind a laminar conductance), which must then
side with the candidate of the truth's own kind."""
import os

import numpy as np
import pytest

from leveler.diagnose import blindtest as bt
from leveler.diagnose import design, effects as fx, fit, separability
from leveler.engine import read_schedule
from leveler.diagnose.model import REPLAY
from leveler.diagnose.runs import load_run

SYSTEM = "900lb"
# the truth: a pipe split behind a conductance (blindtest's line_delay truth, drawn once)
TRUTH = {"tube_volume_m3": 8.2e-5, "conductance_kg_per_s_pa": 6.95e-9, "pipe_share_behind": 0.083}


def truth_params():
    return [TRUTH[p["name"]] for p in bt.TRUTH["line_delay"]["params"]]


@pytest.fixture(scope="module")
def case(cplant, tmp_path_factory):
    """Calibration load steps from the truth; A = the line candidate fitted on them,
    B = the sensor-lag candidate fitted on A's simulated runs (the closest
    look-alike of A that a sensor lag makes on these load steps; as the
    diagnosis's separability test refits, with more starts)."""
    top = tmp_path_factory.mktemp("design")
    logs = top / "logs"
    logs.mkdir()
    rig = bt.rig_config(str(top), SYSTEM, 1)
    rng = np.random.default_rng(1)
    for name, steps, end in bt.schedules(rng, SYSTEM):     # cal1, cal2 and the held-out run
        bt.write_truth_log(cplant, str(logs / f"{name}.csv"), rig, SYSTEM, steps, end, "line_delay",
                           truth_params(), "100Hz", rng)
    prob = fit.Problem(cplant, bt.SYSTEMS[SYSTEM][0], [load_run(str(logs / f"{n}.csv")) for n in ("cal1", "cal2")],
                       REPLAY)
    a = fit.fit_effect(prob, fx.get("line_delay"), starts=8, max_nfev=15, polish=1)["params"]
    on_a = fit.Problem(cplant, prob.config, separability.simulated_runs(prob, "line_delay", a), REPLAY)
    b = fit.fit_effect(on_a, fx.get("sensor_lag"), starts=16, max_nfev=30, polish=2)["params"]
    return {"top": top, "logs": logs, "rig": rig, "prob": prob, "a": a, "b": b}


def test_a_manual_sequence_separates_load_step_lookalikes_and_the_truth_decides(case, cplant):
    prob, a, b = case["prob"], case["a"], case["b"]
    nominal = prob.gap(None, {})
    gap_a, gap_b = prob.gap("line_delay", a), prob.gap("sensor_lag", b)
    # both explain the calibration load steps by the diagnosis's own standard (shrink above 15 %),
    # the look-alike B less well (tick-rate logs of this rig do not leave much room)
    assert gap_a < 0.85 * nominal and gap_b < 0.85 * nominal, (nominal, gap_a, gap_b)

    p = design.propose(prob, ("line_delay", a), ("sensor_lag", b))
    by = {r["schedule"]: r["separation_noise_units"] for r in p["ranked"]}
    best = p["ranked"][0]
    best_load = max(r["separation_noise_units"] for r in p["ranked"] if r["kind"] == "load")
    print(f"nominal {nominal:.3f}, A {gap_a:.3f}, B {gap_b:.3f}; best {best['schedule']} "
          f"{best['separation_noise_units']:.1f}, best load {best_load:.1f}, "
          f"+200 lb {by['step +200 lb for 25 s']:.1f}")
    # every load schedule, the ones like the calibration runs included, tells them apart far
    # less than the proposed manual sequence
    assert best["kind"] == "manual"
    assert best["separation_noise_units"] > 3.0 * best_load
    # safe: it ends back in auto and the supervisor overrode nothing in either simulation
    assert best["steps"][-2][2].get("mode") == design.AUTO and best["schedule"] not in p["unsafe"]

    # written as a schedule file and read back by the simulator's one parser
    path = str(case["top"] / "experiment.csv")
    design.write_schedule(path, p)
    steps, end = read_schedule(path)
    assert end == best["steps"][-1][0]
    assert design.schedule_writes(steps) == design.schedule_writes([tuple(r) for r in best["steps"]])

    # run on the truth through the firmware's register map, logged as a rig logs
    log = str(case["logs"] / "experiment.csv")
    bt.write_truth_log(cplant, log, case["rig"], SYSTEM, steps, end, "line_delay", truth_params(), "100Hz",
                       np.random.default_rng(2), design.schedule_writes(steps))
    run = load_run(log)
    req = design.requested(run.t_s, steps)["manual_spring_valve"]
    manual = req >= 0
    manual[1:] &= manual[:-1]
    assert manual.sum() > 100 and (run.commands["spring_valve"][manual] == req[manual]).all()

    ex = fit.Problem(cplant, bt.SYSTEMS[SYSTEM][0], [run], REPLAY)
    ex_nom, ex_a, ex_b = ex.gap(None, {}), ex.gap("line_delay", a), ex.gap("sensor_lag", b)
    print(f"on the truth's experiment: nominal {ex_nom:.3f}, line_delay {ex_a:.3f}, sensor_lag {ex_b:.3f}")
    # resolved in favour of the truth's kind: its candidate explains the experiment, the look-alike does not
    assert ex_a < 0.5 * ex_nom
    assert ex_a < 0.3 * ex_b


def test_the_blind_test_runs_a_proposed_manual_experiment_on_its_truth(case, cplant):
    """blindtest.run_experiment (the path the blind test takes for look-alikes): the
    proposed experiment.csv with register columns is read by the C parser, run on
    the truth through the register map, and the look-alikes refitted by the
    diagnosis as its own process are scored on it beside the first held-out run:
    the truth's kind is named."""
    p = design.propose(case["prob"], ("line_delay", case["a"]), ("sensor_lag", case["b"]))
    os.makedirs(case["top"] / "diagnosis", exist_ok=True)
    design.write_schedule(str(case["top"] / "diagnosis" / "experiment.csv"), p)
    d = {"cannot_tell_apart": ["line_delay", "sensor_lag"]}
    verdict = bt.run_experiment(cplant, str(case["top"]), d, "line_delay", truth_params(), SYSTEM, "100Hz", 1,
                                ["--fast"])["effect"]
    run = load_run(str(case["logs"] / "experiment.csv"))
    steps, _ = read_schedule(str(case["top"] / "diagnosis" / "experiment.csv"))
    for k, want in design.requested(run.t_s, steps).items():
        manual = want >= 0
        manual[1:] &= manual[:-1]
        assert manual.sum() > 100 and (run.commands[k.replace("manual_", "")][manual] == want[manual]).all(), k
    assert verdict == "line_delay"


def test_the_experiment_is_ranked_on_how_each_candidate_shows_against_none(case):
    """With the model without effect as base (certainty._experiment), a schedule is
    worth the smaller of the pair's separation and how far each candidate lies from
    no effect, both beyond the knife edge: the run joins the held-out ones, where
    the true effect must still show. A leak of zero area is the plant without an
    effect, so nothing can show it; the look-alike pair above both show on the
    schedule chosen for them."""
    prob, a, b = case["prob"], case["a"], case["b"]
    none = (None, {}, prob.config, "none")
    zero = design.propose(prob, ("line_delay", a), ("leak", {"leak_area_m2": 0.0}), base=none)
    assert all(r["each_shows_noise_units"] == 0.0 for r in zero["ranked"])

    p = design.propose(prob, ("line_delay", a), ("sensor_lag", b), base=none)
    worth = [min(r["separation_noise_units"], r["each_shows_noise_units"]) for r in p["ranked"]]
    assert worth[0] == max(worth) and worth[0] > 1.0, worth
    alone = design.propose(prob, ("line_delay", a), ("sensor_lag", b))
    by = {r["schedule"]: r["separation_noise_units"] for r in alone["ranked"]}
    # the pair's own separation on each schedule does not depend on the base
    assert all(abs(by[r["schedule"]] - r["separation_noise_units"]) < 1e-9 for r in p["ranked"])


def test_a_sequence_the_rig_without_either_effect_could_not_run_is_unsafe(case, tmp_path):
    """The base is the rig as it may well be (neither effect): a manual sequence the
    supervisor would override there is not proposed, however safe both candidates
    find it. A rig whose pipe holds 1 in3 instead of 12.5 in3: the compressor run
    against the shut spring valve trips the overpressure cut (supervisor.h), while on
    the config as given every sequence runs as written."""
    prob, a, b = case["prob"], case["a"], case["b"]
    small = tmp_path / "small-pipe.ini"
    small.write_text(f"[config]\ninclude = {os.path.join(bt.CONFIG_DIR, prob.config + '.ini')}\n"
                     "name = small-pipe\n\n[pipe]\nvolume_in3 = 1.0\n")
    as_given = design.propose(prob, ("line_delay", a), ("sensor_lag", b), base=(None, {}, prob.config, "none"))
    on_small = design.propose(prob, ("line_delay", a), ("sensor_lag", b), base=(None, {}, str(small), "none"))
    assert as_given["unsafe"] == []
    against = "compressor 2 x 3 s against the shut spring valve"
    assert against in on_small["unsafe"] and against not in [r["schedule"] for r in on_small["ranked"]]
    # what the small pipe's run overrides: the compressor's requests, nothing else
    steps = next(s for n, s, _ in design.candidate_schedules(float(prob.runs[0].load_n[0])) if n == against)
    run = design.schedule_run(prob.runs[0], steps, 35.0)
    trace = prob.sim.simulate(str(small), run, None, {}, design.CLOSED_LOOP)
    req = design.requested(trace.t_s - trace.t_s[0], steps)["manual_compressor"]
    on = (req == 1)
    on[1:] &= on[:-1]
    assert (trace.commands["compressor"][on] == 0).any()

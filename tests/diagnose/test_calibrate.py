"""Calibrate before blaming (calibrate.py): on logs of a rig whose config differs from
the given one in one nominal value (made by the C plant closed loop with the firmware,
through the C loader's include, as the blind test's mis-set rigs are), the calibration
moves that value back to within a few percent of the rig's, leaves a held-out gap as
small as the rig's own config leaves (the independent expectation: the true model),
and on logs of the given config itself moves nothing."""
import os

import numpy as np
import pytest

from leveler import config as leveler_config
from leveler.diagnose import blindtest as bt
from leveler.diagnose import calibrate, fit, runs
from leveler.diagnose import cplant as cp


def _logs(sim, folder, rig, seed=4):
    """The blind test's three schedules on `rig` (100 Hz logs); (calibration runs, held-out)."""
    rng = np.random.default_rng(seed)
    out = []
    for name, steps, end in bt.schedules(rng, "900lb"):
        path = os.path.join(folder, f"{name}.csv")
        bt.write_truth_log(sim, path, rig, "900lb", steps, end, "none", [], "100Hz", rng)
        out.append(runs.load_run(path))
    return out[:2], out[2:]


def _misset(folder, change):
    spec = next(s for s in bt.family_specs("misset") if s["form"] == change)
    return bt.rig_config(folder, "900lb", 4, spec), spec


@pytest.mark.parametrize("change,want", [("capacity-15%", "compressor_capacity"),
                                         ("vent_cd-25%", "vent_valve_cd"),
                                         ("pipe_volume+30%", "pipe_volume")])
def test_calibration_finds_the_misset_value(cplant, tmp_path, change, want):
    try:
        rig, spec = _misset(str(tmp_path), change)
        truth = leveler_config.resolved(rig)
    except leveler_config.ConfigError as e:
        pytest.skip(f"leveler-sim not available: {e}")
    calib, hold = _logs(cplant, str(tmp_path), rig)
    config = cp.config_path("thesis-900lb")
    rep = calibrate.calibrate(cplant, config, calib, hold, "auto", str(tmp_path), 15.0, progress=lambda m: None)
    assert rep["kept"]
    assert want in rep["moved"]
    p = next(x for x in rep["parameters"] if x["name"] == want)
    sec, key = spec["keys"][0]
    assert p["value"] == pytest.approx(truth[sec][key], rel=0.03)
    # and the interval it states holds the rig's value (an interval that is true)
    assert p["interval"][0] <= truth[sec][key] <= p["interval"][1]
    # as good on the held-out run as the rig's own config (the true model)
    true_gap = fit.Problem(cplant, rig, hold, "auto", fit.start_shifts(hold)).gap(None, {})
    assert rep["holdout_gap"]["after"] <= 1.25 * true_gap
    assert rep["holdout_gap"]["before"] >= 3.0 * true_gap
    # the calibrated config is a config the C loader reads, holding the fitted value
    path = os.path.join(str(tmp_path), "calibrated.ini")
    with open(path, "w") as fh:
        fh.write(rep["ini"])
    assert leveler_config.resolved(path)[sec][key] == pytest.approx(p["value"], rel=1e-12)


def test_one_value_is_found_from_the_grid(cplant, tmp_path):
    """A pipe 30 % larger: from the best of the grid (calibrate.grid_start) the fit lands
    on the rig's pipe, and no worse than a local fit from the config's value."""
    try:
        rig, spec = _misset(str(tmp_path), "pipe_volume+30%")
        truth = leveler_config.resolved(rig)["pipe"]["volume_m3"]
    except leveler_config.ConfigError as e:
        pytest.skip(f"leveler-sim not available: {e}")
    calib, _ = _logs(cplant, str(tmp_path), rig)
    config = cp.config_path("thesis-900lb")
    space = calibrate.Space(config, leveler_config.resolved(config))
    cal = calibrate.Calibrated(cplant, space, calib, "auto", str(tmp_path))
    j = [n.name for n in space.params].index("pipe_volume")
    ss = lambda u: float(np.sum(cal.data_residual(u) ** 2))     # noqa: E731
    local = calibrate.fit_subset(cal, space.u0, [j], 12)
    found = calibrate.fit_subset(cal, calibrate.grid_start(cal, space.u0, j, ss(space.u0)), [j], 12)
    assert space.values(found)[j] == pytest.approx(truth, rel=0.03)
    assert ss(found) <= ss(local) * (1.0 + 1e-9)


def test_a_larger_pipe_and_a_larger_spring_are_reported_alike(cplant, tmp_path):
    """The blind test's misset seed 7: a pipe 30 % larger logged at rig rate (20-50 Hz,
    jittered). The spring's volume 1.3 % larger holds the same air at the same
    pressures, and neither the calibration runs nor the held-out run (steps, no
    experiment) tell the two apart: the calibration moves one and reports the other
    as alike, moves nothing else, and a user is told both. (Before the discharge's
    chatter was replayed by its track, the exponent was chosen first and the
    held-out run chose the pipe: calibrate.held_out_first, now tested on seed 13.)"""
    spec = next(s for s in bt.family_specs("misset") if s["form"] == "pipe_volume+30%")
    try:
        spec, system, kind, _, _ = bt.form_logs(cplant, str(tmp_path), 7, spec)
    except leveler_config.ConfigError as e:
        pytest.skip(f"leveler-sim not available: {e}")
    assert (system, kind) == ("900lb", "rig")
    logs = [runs.load_run(os.path.join(str(tmp_path), "logs", f"{n}.csv")) for n in ("cal1", "cal2", "hold")]
    config = cp.config_path("thesis-900lb")
    rep = calibrate.calibrate(cplant, config, logs[:2], logs[2:], "auto", str(tmp_path), 15.0, progress=lambda m: None)
    assert rep["kept"]
    told = set(rep["moved"]) | {a["name"] for a in rep["alike"]}
    assert {"pipe_volume", "spring_volume"} <= told
    assert len(rep["moved"]) == 1 and rep["moved"][0] in ("pipe_volume", "spring_volume")
    spring = next(x for x in rep["parameters"] if x["name"] == "spring_volume")
    if spring["moved"]:     # the air of 30 % of the pipe's volume is about 1.4 % of the spring's
        ratio = 0.3 * leveler_config.resolved(config)["pipe"]["volume_m3"] / spring["config"]
        assert spring["change_pct"] == pytest.approx(100.0 * ratio, rel=0.5)


def test_the_second_calibration_stops_where_the_held_out_run_is_best(cplant, tmp_path):
    """The blind test's misset seed 13: a pipe 30 % larger logged at rig rate. The
    forward selection takes the spring's volume first (its +1.3 % holds the pipe's
    air); the pipe alone explains the held-out run better (0.246 against 0.257), and
    the calibration from it adds the compressor, which lowers the calibration runs'
    gap and not the held-out one. The pipe alone, the held-out run's best along that
    path, is taken: the rig's pipe within 5 % and inside its interval, nothing else
    chosen. (Before the discharge's track the exponent came first, and the pipe with
    the compressor left the held-out run worse than it: the exponent stood.)"""
    spec = next(s for s in bt.family_specs("misset") if s["form"] == "pipe_volume+30%")
    try:
        spec, system, kind, _, _ = bt.form_logs(cplant, str(tmp_path), 13, spec)
        truth = leveler_config.resolved(os.path.join(str(tmp_path), "rig.ini"))["pipe"]["volume_m3"]
    except leveler_config.ConfigError as e:
        pytest.skip(f"leveler-sim not available: {e}")
    assert (system, kind) == ("900lb", "rig")
    logs = [runs.load_run(os.path.join(str(tmp_path), "logs", f"{n}.csv")) for n in ("cal1", "cal2", "hold")]
    config = cp.config_path("thesis-900lb")
    said = []
    rep = calibrate.calibrate(cplant, config, logs[:2], logs[2:], "auto", str(tmp_path), 15.0, progress=said.append)
    assert any("calibrating from it" in m for m in said)
    assert any("the held-out runs are best with pipe_volume" in m for m in said)
    assert rep["kept"] and rep["moved"] == ["pipe_volume"]
    p = next(x for x in rep["parameters"] if x["name"] == "pipe_volume")
    assert p["value"] == pytest.approx(truth, rel=0.05)
    assert p["interval"][0] <= truth <= p["interval"][1]
    assert [x["name"] for x in rep["parameters"] if x["chosen"]] == ["pipe_volume"]


class _RoughResidual:
    """A calibration whose residual in one value is a staircase (steps 1/20 of the
    range wide, flat to a finite difference) except in a smooth basin +-0.05 around
    the truth at 0.8: the shape of a closed loop whose valve switchings move by
    whole ticks. The calibration's interface as grid_start and fit_subset use it."""
    TRUTH = 0.8

    def residual(self, u):
        d = float(u[0]) - self.TRUTH
        return np.array([d if abs(d) < 0.05 else round(20.0 * d) / 20.0])

    data_residual = residual

    def data_cost_below(self, u, bound):
        c = float(np.sum(self.residual(u) ** 2))
        return c if c < bound else None


def test_the_grid_crosses_a_rough_residual():
    """A local fit from 0.5 stays on the staircase; from the grid's best start
    (calibrate.grid_start) it reaches the basin and the truth."""
    cal, u0 = _RoughResidual(), np.array([0.5])
    ss0 = float(np.sum(cal.residual(u0) ** 2))
    local = calibrate.fit_subset(cal, u0, [0], 12)
    assert abs(local[0] - 0.5) < 0.05
    found = calibrate.fit_subset(cal, calibrate.grid_start(cal, u0, 0, ss0), [0], 12)
    assert found[0] == pytest.approx(cal.TRUTH, abs=1e-3)


def test_trials_in_two_processes_give_the_serial_result(cplant, tmp_path):
    """The forward selection's trials run in forked processes (jobs 2): the same
    values, the same choice and the same simulation count as one after the other."""
    try:
        rig, _ = _misset(str(tmp_path), "capacity-15%")
        leveler_config.resolved(rig)
    except leveler_config.ConfigError as e:
        pytest.skip(f"leveler-sim not available: {e}")
    calib, _ = _logs(cplant, str(tmp_path), rig)
    config = cp.config_path("thesis-900lb")
    space = calibrate.Space(config, leveler_config.resolved(config))
    out = []
    for jobs in (1, 2):
        cal = calibrate.Calibrated(cplant, space, calib, "auto", str(tmp_path))
        u, chosen, singles = calibrate.fit_calibration(cal, jobs=jobs)
        out.append((u, chosen, singles, cal.nsim))
    (u1, c1, s1, n1), (u2, c2, s2, n2) = out
    assert c1 == c2 and c1 and np.array_equal(u1, u2)
    assert s1.keys() == s2.keys() and all(np.array_equal(s1[k], s2[k]) for k in s1)
    assert n1 == n2 > 0


def test_calibration_moves_nothing_on_the_configs_own_logs(cplant, tmp_path):
    try:
        rig = bt.rig_config(str(tmp_path), "900lb", 4)
        leveler_config.resolved(rig)
    except leveler_config.ConfigError as e:
        pytest.skip(f"leveler-sim not available: {e}")
    calib, hold = _logs(cplant, str(tmp_path), rig)
    rep = calibrate.calibrate(cplant, cp.config_path("thesis-900lb"), calib, hold, "auto", str(tmp_path), 15.0,
                              progress=lambda m: None)
    assert rep["moved"] == []
    assert not rep["kept"]


def test_the_parameters_come_from_the_physics_not_a_test_set():
    names = {n.name for n in calibrate.NOMINALS}
    # every one is a config key the C loader knows, with a range around the config's value
    try:
        doc = leveler_config.resolved(cp.config_path("thesis-900lb-diaphragm"))
    except leveler_config.ConfigError as e:
        pytest.skip(f"leveler-sim not available: {e}")
    for n in calibrate.applicable(doc):
        v = doc[n.section][n.key]
        lo, hi = n.bounds(v)
        assert lo < v < hi and (not n.cap or hi <= n.cap), n.name
    assert "accumulator_cd" in {n.name for n in calibrate.applicable(doc)}
    assert "accumulator_cd" not in {n.name for n in calibrate.applicable(
        leveler_config.resolved(cp.config_path("thesis-900lb")))}
    assert len(names) == len(calibrate.NOMINALS)


def test_values_carry_to_a_run_config_with_more_parameters(cplant):
    """Published figures of accumulator runs diagnosed against a config without one
    (helper-found crash: shapes (10,) against (9,)): each shared parameter moves by the
    calibration's factor (its value, for the absolute exponent), the accumulator's
    own keeps the run config's value."""
    plain = calibrate.Space(cp.config_path("thesis-900lb"), leveler_config.resolved(cp.config_path("thesis-900lb")))
    acc_path = cp.config_path("thesis-900lb-diaphragm")
    acc = calibrate.Space(acc_path, leveler_config.resolved(acc_path))
    assert len(acc.params) == len(plain.params) + 1
    u = np.full(len(plain.params), 0.75)
    vals = plain.values(u)
    got = calibrate._carried(plain, vals, acc)
    for i, n in enumerate(acc.params):
        j = next((k for k, m in enumerate(plain.params) if m.key == n.key and m.section == n.section), None)
        if j is None:
            assert got[i] == acc.base[i]
        elif n.log:
            assert got[i] == pytest.approx(acc.base[i] * vals[j] / plain.base[j], rel=1e-15)
        else:
            assert got[i] == vals[j]

"""A leak seen with the valves shut (shut_spring.py): on logs of the 900 lb rig made by
the blind test's leak truth (a capillary law, m = K (P2^2 - Pa^2): not the candidate's
orifice), the runs' quiet starts show it, and the leak found there loses the air the
logs lose (the P2 slope of the stretch, a straight line through the logged samples,
against the same line through the simulation with that leak). On logs of the config
itself, and of a rig whose vent's Cd is 25 % low (a mis-set value acts only when a
valve opens), nothing is seen."""
import os

import numpy as np
import pytest

from leveler import config as leveler_config
from leveler.diagnose import blindtest as bt
from leveler.diagnose import cplant as cp
from leveler.diagnose import effects as fx
from leveler.diagnose import runs, shut_spring
from leveler.diagnose.context import Ask


def _calib_logs(sim, folder, rig, effect="none", params=()):
    """The blind test's two calibration schedules on `rig` (100 Hz logs)."""
    rng = np.random.default_rng(7)
    out = []
    for name, steps, end in bt.schedules(rng, "900lb")[:2]:
        path = os.path.join(folder, f"{name}.csv")
        bt.write_truth_log(sim, path, rig, "900lb", steps, end, effect, list(params), "100Hz", rng)
        out.append(runs.load_run(path))
    return out


def _ask(sim):
    return Ask(None, sim, cp.config_path("thesis-900lb"), "auto", list(fx.NAMES), 1, lambda m: None, None, None)


def _rig(folder, misset=None):
    try:
        rig = bt.rig_config(folder, "900lb", 7, misset)
        leveler_config.resolved(rig)
    except leveler_config.ConfigError as e:
        pytest.skip(f"leveler-sim not available: {e}")
    return rig


def _slope(t, p2):
    return float(np.polyfit(t, p2, 1)[0])


def test_a_leak_is_seen_and_sized_by_the_air_it_loses(cplant, tmp_path):
    rig = _rig(str(tmp_path))
    calib = _calib_logs(cplant, str(tmp_path), rig, "leak", [8e-17])
    seen = shut_spring.leak_seen(_ask(cplant), calib)
    assert seen is not None and seen["effect"] == "leak"
    assert seen["gap"][1] < 0.8 * seen["gap"][0]
    for run in calib:
        short = shut_spring.stretch(run)
        logged = _slope(short.t_s, short.signals["p_spring_pa"])
        assert logged < -100.0          # Pa/s: the truth's leak is there to be seen
        trace = cplant.simulate(cp.config_path("thesis-900lb"), short, "leak", seen["params"], "auto")
        simulated = _slope(short.t_s, trace.signals["p_spring_pa"])
        assert simulated == pytest.approx(logged, rel=0.3)


@pytest.mark.parametrize("misset", [None, "vent_cd-25%"])
def test_no_leak_is_seen_where_there_is_none(cplant, tmp_path, misset):
    spec = next(s for s in bt.family_specs("misset") if s["form"] == misset) if misset else None
    rig = _rig(str(tmp_path), spec)
    calib = _calib_logs(cplant, str(tmp_path), rig)
    assert all(shut_spring.stretch(r) is not None for r in calib)
    assert shut_spring.leak_seen(_ask(cplant), calib) is None

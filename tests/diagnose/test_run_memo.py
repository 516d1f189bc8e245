"""What a fit works out once per run instead of once per simulation (run_memo,
CPlant._window_config) changes no figure: a replay from the memo is the replay
worked out afresh, a memo never answers for another run, and the start's motor
speed is shared only across values that cannot reach the pipe."""
import os
from dataclasses import replace

import numpy as np
import pytest

from conftest import thesis_schedule
from leveler.diagnose import cplant as cp
from leveler.diagnose import fit, run_memo
from leveler.diagnose.model import REPLAY
from leveler.diagnose.runs import Run
from leveler.diagnose.start_state import initial_state
from test_unlogged import ACC, truth_run

CONFIG = "thesis-900lb"


def coarse_run(cplant, seed, end=20.0):
    """A 25 Hz log with jittered stamps of a closed-loop run with a load step."""
    t, load = thesis_schedule(end=end, on=3.0, off=end)
    tr = cplant._closed_loop(CONFIG, t, load, 0, [], [np.nan] * 4 + [0.0])
    rng = np.random.default_rng(seed)
    ts = np.unique(np.round(np.arange(0.0, end, 0.04) + rng.uniform(-0.008, 0.008, int(end / 0.04)), 4))
    ts[0] = 0.0
    idx = np.clip(np.searchsorted(t, ts + 1e-9, side="right") - 1, 0, len(t) - 1)
    sig = {k: np.interp(ts, t, v) for k, v in tr.signals.items()}
    return Run(f"coarse{seed}.csv", ts, sig, load[idx], {k: v[idx] for k, v in tr.commands.items()})


def copied(run):
    """The same log in new arrays (another key for the memo)."""
    return Run(run.path, run.t_s.copy(), {k: v.copy() for k, v in run.signals.items()}, run.load_n.copy(),
               {k: v.copy() for k, v in run.commands.items()})


def replay(cplant, run):
    tr = cplant.simulate(CONFIG, run, "leak", {"leak_area_m2": 2e-7}, REPLAY)
    return tr, fit.run_residual(run, tr)


def test_a_replay_from_the_memo_is_the_replay_worked_out_afresh(cplant):
    a, b = coarse_run(cplant, 1), coarse_run(cplant, 2)
    run_memo.clear()
    first_a, first_b = replay(cplant, a), replay(cplant, b)
    again_a, again_b = replay(cplant, a), replay(cplant, b)          # from the memo, interleaved
    fresh_a = replay(cplant, copied(a))                               # new arrays: worked out again
    shifted = replay(cplant, replace(a, start_shift=(0.0, 0.0)))      # a copy sharing the arrays
    for got in (again_a, fresh_a, shifted):
        for s, v in first_a[0].signals.items():
            assert np.array_equal(got[0].signals[s], v), s
        assert np.array_equal(got[1], first_a[1])
    assert np.array_equal(again_b[1], first_b[1])
    # the two logs differ (the jitter): a memo answering for the other would show
    assert not np.array_equal(first_a[1], first_b[1])


def test_the_memo_hands_out_arrays_no_caller_can_change(cplant):
    run = coarse_run(cplant, 3, end=5.0)
    rel, grid, idx, cmds, load, back = run_memo.of_run(run, "grid", cp.fine_grid)
    for a in (rel, grid, idx, load, back, *cmds.values()):
        with pytest.raises(ValueError):
            a[0] = a[0]
    assert run.t_s.flags.writeable and run.signals["p_spring_pa"].flags.writeable   # the run's own stay


def _config(tmp_path, name, body):
    path = os.path.join(str(tmp_path), name + ".ini")
    with open(path, "w") as fh:
        fh.write(f"[config]\ninclude = {cp.config_path(ACC)}\nname = {name}\n\n{body}")
    return path


def test_the_start_speed_is_shared_only_across_values_behind_the_shut_valve(cplant, tmp_path):
    """The compressor charges the pipe behind the shut spring valve at the start:
    no value of the spring's side reaches P1 there (a shut valve's flow is exactly
    zero), so the start's motor speed fitted to P1 is the same to the bit; the
    pipe's volume does reach it."""
    run, _ = truth_run(cplant, 60.0)
    init, duty = initial_state(run)
    n = int(np.searchsorted(run.t_s, run.t_s[0] + cp.OMEGA_WINDOW_S))
    assert duty > 0.5 and not np.any(run.commands["spring_valve"][:n])
    spring = _config(tmp_path, "spring", "[spring]\nvolume_m3 = 0.004\n\n[spring_valve]\ncd_into_spring = 0.5\n\n"
                                         "[platform]\ndamping_down_n_s_per_m = 3000\n")
    pipe = _config(tmp_path, "pipe", "[pipe]\nvolume_m3 = 0.00025\n")
    fresh = {c: cp.CPlant().start_motor_speed(c, run, list(init), duty) for c in (ACC, spring, pipe)}
    assert fresh[spring] == fresh[ACC]
    assert fresh[pipe] != fresh[ACC]
    assert abs(fresh[ACC][0] - 60.0) < 3.0
    shared = cp.CPlant()
    for c in (ACC, spring, pipe, spring):
        assert shared.start_motor_speed(c, run, list(init), duty) == fresh[c], c

"""The engine's handle API (host_sim/diagnose/engine.h) through its one binding
(leveler.engine). Each check has an independent expectation: many parameter
sets in one request against one request per set; a run after other runs
against the same run on a fresh handle; a config's effects at their nominal
values against the same config without them; the loader's own messages."""
import numpy as np
import pytest

from conftest import LB, ROOT, thesis_schedule
from leveler import engine
from leveler.diagnose import effects as fx
from leveler.errors import InputError

THESIS = f"{ROOT}/host_sim/configs/thesis-900lb.ini"


@pytest.fixture(scope="module")
def eng(cplant):
    return engine.Engine(THESIS)


def _sets(name, fractions):
    """Parameter sets of one effect: each parameter at a fraction of its range."""
    e = fx.get(name)
    out = np.zeros((len(fractions), engine.MAX_MODELS, engine.MAX_PARAMS))
    for k, f in enumerate(fractions):
        out[k, 0, :len(e.params)] = [q.lo + f * (q.hi - q.lo) for q in e.params]
    kinds = np.zeros(engine.MAX_MODELS, dtype=np.int32)
    kinds[0] = e.effect_id
    return kinds, out


def test_many_parameter_sets_in_one_request_are_the_runs_one_by_one(eng):
    t, load = thesis_schedule(end=20.0, on=2.0, off=12.0)
    kinds, sets = _sets("leak", [0.0, 0.02, 0.05])
    many, act = eng.run(t, load, init=[np.nan] * 4 + [0.0], kinds=kinds, params=sets)
    assert many.shape == (3, len(t), 4) and act.shape == (3, len(t), 4)
    for k in range(3):
        one, one_act = eng.run(t, load, init=[np.nan] * 4 + [0.0], kinds=kinds, params=sets[k])
        assert np.array_equal(many[k], one) and np.array_equal(act[k], one_act)
    # and the sets differ: a larger leak holds the platform lower at the end
    assert many[2, -1, 0] < many[0, -1, 0] - 1e-4


def test_a_handle_keeps_nothing_between_runs(cplant):
    """Closed loop with register writes (manual mode), then a run without: the
    second equals itself on a fresh handle (no writes handed on, no state left)."""
    t, load = thesis_schedule(end=10.0, on=1.0, off=6.0)
    writes = [(2.0, {"manual_compressor": 1, "mode": 2}), (4.0, {"mode": 0})]
    used = engine.Engine(THESIS)
    with_writes, _ = used.run(t, load, writes=writes, init=[np.nan] * 4 + [0.0])
    after, _ = used.run(t, load, init=[np.nan] * 4 + [0.0])
    fresh, _ = engine.Engine(THESIS).run(t, load, init=[np.nan] * 4 + [0.0])
    assert np.array_equal(after, fresh)
    assert not np.array_equal(with_writes, fresh)      # the writes did act in their own run


def test_effects_at_nominal_are_the_nominal_plant(cplant, tmp_path):
    t, load = thesis_schedule(end=20.0, on=2.0, off=12.0)
    cfg = tmp_path / "leaky.ini"
    cfg.write_text(f"[config]\ninclude = {THESIS}\nname = leaky\n\n[effect.leak]\nleak_area_m2 = 2e-8\n")
    nominal, _ = engine.Engine(THESIS).run(t, load)
    at_nominal, _ = engine.Engine(cfg, effects_nominal=True).run(t, load)
    leaky, _ = engine.Engine(cfg).run(t, load)
    assert np.array_equal(at_nominal, nominal)
    assert abs(leaky[-1, 1] - nominal[-1, 1]) > 100.0     # the leak itself is on without the flag


def test_the_engine_names_what_it_refuses(eng, tmp_path):
    t, load = thesis_schedule(end=1.0)
    with pytest.raises(engine.EngineError, match="effect table 2 is not in this build"):
        eng.run(t, load, catalogue=engine.TRUTH2, kinds=[101, 0], params=np.zeros((2, 8)))
    with pytest.raises(engine.EngineError, match="closed loop needs the 10 ms tick grid"):
        eng.run(t * 1.5, load)
    with pytest.raises(engine.EngineError, match=r"commands has shape \(\d+, 3\)"):
        eng.run(t, load, commands=np.zeros((len(t), 3)))
    with pytest.raises(engine.EngineError, match="load has shape"):
        eng.run(t, load[:-1])
    bad = tmp_path / "bad.ini"
    bad.write_text(f"[config]\ninclude = {THESIS}\n\n[spring]\nvolume_in3 = -3\n")
    with pytest.raises(InputError, match=r"bad\.ini:\d+"):
        engine.Engine(bad)


def test_the_resolved_config_is_the_files(eng):
    doc = eng.config_json()
    assert doc["scenario"]["base_load_n"] == pytest.approx(900 * LB, rel=1e-9)
    assert eng.algorithm == doc["controller"]["algorithm"]


def test_runs_from_threads_take_turns(cplant):
    """The firmware in the loop is one per process: closed-loop runs from four
    threads at once (as a Dask worker with several threads would make them) give
    each the run it gives alone."""
    import threading
    t, load = thesis_schedule(end=8.0, on=1.0, off=5.0)
    alone, _ = engine.Engine(THESIS).run(t, load, init=[np.nan] * 4 + [0.0])
    got = [None] * 16       # four rounds of four (without the turns, 8 of 20 differed)

    def one(k):
        got[k] = engine.Engine(THESIS).run(t, load, init=[np.nan] * 4 + [0.0])[0]

    for r in range(4):
        threads = [threading.Thread(target=one, args=(4 * r + k,)) for k in range(4)]
        for th in threads:
            th.start()
        for th in threads:
            th.join()
    assert all(np.array_equal(g, alone) for g in got)

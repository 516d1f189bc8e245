"""What logs resolve (runs.sample_interval, effects.Effect.resolved, candidates.rank):
a valve whose fitted strokes (delay plus lag) all last less than one sample of the
logs is what a replayed log's switch timing blurs, and is ranked after the
candidates the logs resolve. The expectations are the sampling the logs were
written with and the sums of the fitted times."""
import json

import numpy as np
import pytest

from leveler.diagnose import blindtest, candidates, effects, runs
from leveler.diagnose.evidence_figures import PublishedFigures
from leveler.diagnose.evidence_runs import RunLogs


def _log(tmp_path, name, kind, seed):
    t = blindtest.log_times(np.random.default_rng(seed), kind, 20.0)
    path = tmp_path / name
    runs.write_run(path, t, {"height_m": np.full(t.size, 0.38), "p_spring_pa": np.full(t.size, 4.0e5)},
                   np.full(t.size, 4000.0))
    return runs.load_run(path), float(np.median(np.diff(t)))


def test_the_finest_logs_median_sample_interval_is_what_the_logs_resolve(tmp_path):
    rig = [_log(tmp_path, f"rig{s}.csv", "rig", s) for s in (1, 2, 3)]
    lo, hi = blindtest.LOG_KINDS["rig"][:2]
    for _, median in rig:                       # 20-50 Hz with 20 % jitter: the median is the rate's period
        assert 1.0 / hi - 2e-4 <= median <= 1.0 / lo + 2e-4
    assert runs.sample_interval([r for r, _ in rig]) == pytest.approx(min(m for _, m in rig), abs=1e-9)
    fine, _ = _log(tmp_path, "fine.csv", "100Hz", 4)
    assert RunLogs().resolution_s([r for r, _ in rig] + [fine]) == pytest.approx(0.01, abs=1e-9)
    assert PublishedFigures().resolution_s([fine]) == 0.0     # figures carry no sampling of their own


def _entry(name, shrink, **values):
    e = effects.get(name)
    v = dict(e.nominal(), **values)
    return {"effect": name, "shrink_pct": shrink, "params": {k: {"value": x} for k, x in v.items()}}


def test_a_valve_faster_than_one_sample_ranks_after_what_the_logs_resolve():
    def ranking():
        # strokes: opening 5 + 10 ms, closing 12 + 10 ms; the longest 22 ms
        return [_entry("leak", 20.0), _entry("valve_dynamics", 40.0, open_delay_s=0.005, close_delay_s=0.012,
                                            opening_tau_s=0.010)]
    coarse = ranking()
    candidates.rank(coarse, 0.0245)             # a 41 Hz rig log: 22 ms is under one sample
    assert [r["effect"] for r in coarse] == ["leak", "valve_dynamics"]
    assert coarse[1]["under_resolution"] and coarse[1]["rank"] == 2 and "under_resolution" not in coarse[0]
    for interval in (0.010, 0.022, 0.0):        # 100 Hz, exactly one sample, no sampling known
        fine = ranking()
        candidates.rank(fine, interval)
        assert [r["effect"] for r in fine] == ["valve_dynamics", "leak"]
        assert not any(r.get("under_resolution") for r in fine)


def test_effects_without_strokes_are_always_resolved():
    leak = effects.get("leak")
    assert leak.strokes == ()
    assert leak.resolved(leak.nominal(), 10.0)
    assert effects.get("valve_dynamics").strokes     # the catalogue gives the valve its strokes


def test_strokes_naming_no_parameter_of_the_effect_are_refused(tmp_path):
    doc = json.load(open(effects.CATALOGUE))
    valve = next(e for e in doc["effects"] if e["name"] == "valve_dynamics")
    valve["strokes"] = [["open_delay_s", "opening_lag_s"]]
    path = tmp_path / "effects.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(ValueError, match=r"effects\.json: effect valve_dynamics: strokes: .*opening_lag_s"):
        effects.load(str(path))

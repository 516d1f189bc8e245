"""Calibrate before blaming, where the calibration and an effect explain the held-out runs
alike (calibration_path.effect_first): the calibration stands, unless it needed a value at
the edge of the range a config may be wrong by (calibrate.NOMINALS' rel factors). There a
user would have had to mis-set the value by more than the physics allows, and the effect
is named with the calibration as its look-alike. A physical limit (a discharge
coefficient's cap, the polytropic exponent's 1.0 .. 1.4) is not such an edge. The
ranges are calibrate.NOMINALS' own, applied to a config value here."""
import pytest

from leveler.diagnose import calibrate, calibration_path as cp


def _param(name, config, value, moved=True):
    n = next(x for x in calibrate.NOMINALS if x.name == name)
    lo, hi = n.bounds(config)
    return {"name": name, "config": config, "value": value, "change_pct": 100.0 * (value / config - 1.0),
            "range": [lo, hi], "at_bound": value <= lo * (1 + 1e-9) or value >= hi * (1 - 1e-9),
            "moved": moved}


def _calibration(params, g_cal):
    return {"kept": True, "moved": [p["name"] for p in params if p["moved"]], "parameters": params,
            "holdout_gap": {"before": 2.7, "after": g_cal}, "why": f"held-out gap 2.7 -> {g_cal}, kept",
            "ini": "cal.ini"}


def _decide(params, g_cal, g_fx, gate=0.2):   # fit.NOISE_GAIN x a 0.41 noise gap
    cal = _calibration(params, g_cal)
    named = cp.effect_first(cal, {"effect": "line_delay", "holdout_gap": g_fx}, gate, lambda *_: None)
    return named, cal


def test_a_pipe_volume_pinned_at_twice_the_config_gives_way_to_an_alike_effect():
    named, cal = _decide([_param("pipe_volume", 2.0e-4, 4.0e-4)], g_cal=0.636, g_fx=0.709)
    assert named
    assert not cal["kept"] and cal["superseded_by"] == "line_delay"
    assert cal["rival"]["moved"] == ["pipe_volume"] and cal["rival"]["effect"] == "line_delay"
    assert "edge of its range" in cal["why"]


def test_the_same_value_inside_its_range_stands():
    named, cal = _decide([_param("pipe_volume", 2.0e-4, 3.0e-4)], g_cal=0.636, g_fx=0.709)
    assert not named
    assert cal["kept"] and cal["rival"]["effect"] == "line_delay"


def test_a_pinned_value_stands_when_the_effect_is_not_alike():
    named, cal = _decide([_param("pipe_volume", 2.0e-4, 4.0e-4)], g_cal=0.300, g_fx=0.709)
    assert not named and cal["kept"] and "rival" not in cal


@pytest.mark.parametrize("name,config,value", [("polytropic_exponent", 1.2, 1.4),
                                               ("polytropic_exponent", 1.2, 1.0),
                                               ("spring_valve_cd_in", 0.8, 1.0)])
def test_a_physical_limit_is_no_edge(name, config, value):
    p = _param(name, config, value)
    assert p["at_bound"]
    named, cal = _decide([p], g_cal=0.636, g_fx=0.709)
    assert not named and cal["kept"]


def test_a_discharge_coefficient_at_its_lower_factor_is_an_edge():
    named, cal = _decide([_param("spring_valve_cd_in", 0.8, 0.4)], g_cal=0.636, g_fx=0.709)
    assert named and cal["superseded_by"] == "line_delay"

"""Effects in the config ([effect.NAME] sections, docs/config-format.md): the
one C plant runs them for every program. Checked against the diagnosis
library asked for the same effect explicitly (an independent route through
its own request arrays), and the loader's file:line errors."""
import os
import subprocess

import numpy as np
import pytest

from leveler import config as lcfg
from leveler import runlog
from leveler.diagnose import cplant as cp
from leveler.diagnose import effects as fx
from leveler.diagnose.model import REPLAY
from leveler.diagnose.runs import Run

BASE = os.path.join(cp.CONFIG_DIR, "thesis-900lb.ini")


def three_quarters(e):
    """Each parameter three quarters up its fitting range (the middle of a symmetric range is 'off')."""
    return {p.name: (p.lo ** 0.25 * p.hi ** 0.75 if p.log else 0.25 * p.lo + 0.75 * p.hi) for p in e.params}


def write_config(path, sections, name="fx-rig"):
    lines = ["[config]", f"include = {BASE}", f"name = {name}", ""]
    for effect, params in sections.items():
        lines.append(f"[effect.{effect}]")
        lines += [f"{k} = {v!r}" for k, v in params.items()]
        lines.append("")
    path.write_text("\n".join(lines))
    return str(path)


def sim(config, log):
    p = subprocess.run([lcfg.find_sim(), "--config", config, "--log", str(log), "--quiet"],
                       capture_output=True, text=True)
    return p


def from_config_start(cplant, config, kind, values, t, load):
    """The engine in closed loop from the config's own initial state (init None), as leveler-sim runs."""
    kinds, p = cp.effect_arrays(kind, values)
    out, _ = cplant.handle(config).run(t, load, kinds=kinds, params=p)
    return out


@pytest.mark.parametrize("name", fx.NAMES)
def test_leveler_sim_runs_the_configs_effect(cplant, tmp_path, name):
    e = fx.get(name)
    q = three_quarters(e)
    assert sim(write_config(tmp_path / "fx.ini", {name: q}), tmp_path / "fx.csv").returncode == 0
    assert sim(BASE, tmp_path / "nominal.csv").returncode == 0
    log = runlog.read(str(tmp_path / "fx.csv"))
    nominal = runlog.read(str(tmp_path / "nominal.csv"))
    t = np.ascontiguousarray(log.t_s, dtype=float)
    load = np.ascontiguousarray(log.load_n, dtype=float)
    ref = from_config_start(cplant, BASE, e.effect_id, [q[p.name] for p in e.params], t, load)
    # the plant's own state (true_*, 1e-9 m and 1e-3 Pa in the log) against the library's
    # transducers (which report it as is without sensor_lag); the effect moves far more
    h, p2 = (np.asarray(log.column(c), dtype=float) for c in ("true_height_m", "true_p_spring_pa"))
    if name != "sensor_lag":
        assert np.max(np.abs(h - ref[:, 0])) < 2e-9
        assert np.max(np.abs(p2 - ref[:, 1])) < 2e-3
    moved = np.max(np.abs(h - np.asarray(nominal.column("true_height_m"), dtype=float)))
    assert moved > 1e-4 or name == "sensor_lag"
    if name == "sensor_lag":   # what the firmware read lags the plant (its reading of the same run)
        read = np.asarray(log.height_m) - np.asarray(nominal.height_m)
        assert np.max(np.abs(read)) > 1e-4


@pytest.fixture(scope="module")
def step_run(cplant):
    t = np.round(np.arange(0.0, 20.0 + 1e-9, 0.01), 2)
    load = np.where(t >= 2.0, 1100.0, 900.0) * 4.4482216152605
    closed = cplant.generate("thesis-900lb", t, load, None, [])
    return Run("mem.csv", closed.t_s, closed.signals, load, closed.commands)


@pytest.mark.parametrize("name", fx.NAMES)
def test_the_diagnosis_sees_the_configs_effect_as_its_own(cplant, tmp_path, step_run, name):
    """A config with [effect.NAME] replays a log exactly as the base config with the
    effect asked for (start state included): what --write-config writes is what the fit had."""
    q = three_quarters(fx.get(name))
    cfg = write_config(tmp_path / "fx.ini", {name: q})
    a = cplant.simulate(cfg, step_run, None, {}, REPLAY)
    b = cplant.simulate(BASE, step_run, name, q, REPLAY)
    for s in ("height_m", "p_spring_pa", "p_pipe_pa"):
        assert np.array_equal(a.signals[s], b.signals[s]), s


def test_an_effect_asked_for_runs_beside_the_configs(cplant, tmp_path, step_run):
    q = {"open_delay_s": 0.07, "close_delay_s": 0.03, "opening_tau_s": 0.05}
    cfg = write_config(tmp_path / "vd.ini", {"valve_dynamics": q})
    leak = {p.name: p.hi for p in fx.get("leak").params}
    a = cplant.simulate(cfg, step_run, "leak", leak, REPLAY)
    b = cplant.simulate(BASE, step_run, "valve_dynamics+leak", {**q, **leak}, REPLAY)
    assert np.allclose(a.signals["p_spring_pa"], b.signals["p_spring_pa"], rtol=0, atol=1e-6)
    with pytest.raises(RuntimeError, match="cannot run together"):
        cplant.simulate(cfg, step_run, "valve_dynamics", q, REPLAY)


def test_dump_config_lists_the_effects(tmp_path):
    cfg = write_config(tmp_path / "t.ini", {"thermal": {"tau_thermal_s": 12.5}})
    doc = lcfg.resolved(cfg)
    # the key given, and the catalogue's nominal values of the others (off: the base model)
    assert doc["effects"] == {"thermal": dict(fx.BY_NAME["thermal"].nominal(), tau_thermal_s=12.5)}
    assert lcfg.resolved(BASE)["effects"] == {}
    # a parameter not given keeps the catalogue's nominal value
    cfg = write_config(tmp_path / "f.ini", {"friction": {"coulomb_n": 40.0}})
    f = lcfg.resolved(cfg)["effects"]["friction"]
    assert f == {p.name: (40.0 if p.name == "coulomb_n" else p.nominal) for p in fx.get("friction").params}


@pytest.mark.parametrize("sections, line, words", [
    ({"thermal": {"tau_thermal_s": 900.0}}, 6, "out of range [0, 600]"),
    ({"valvedyn": {"open_delay_s": 0.1}}, 6, "unknown effect 'valvedyn'"),
    ({"thermal": {"open_delay_s": 0.1}}, 6, "unknown parameter of thermal (its parameters: tau_thermal_s, wall_share, tau_wall_s, inlet_rise_rel)"),
    ({"thermal": {"tau_thermal_s": 5.0}, "leak": {"leak_area_m2": 1e-7}, "friction": {"coulomb_n": 5.0}},
     12, "at most 2 effects in one config"),
])
def test_errors_name_the_file_line_and_key(tmp_path, sections, line, words):
    cfg = write_config(tmp_path / "bad.ini", sections)
    p = sim(cfg, tmp_path / "x.csv")
    assert p.returncode == 2
    assert f"{cfg}:{line}: [effect." in p.stderr and words in p.stderr, p.stderr


def ctlbench(args, out):
    exe = os.path.join(os.path.dirname(lcfg.find_sim()), "leveler-ctlbench")
    p = subprocess.run([exe, "--short", "--no-plots", "--quiet", "--out", str(out)] + args,
                       capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    import json
    with open(out / "scorecard.json") as fh:
        return {s["name"]: s for s in json.load(fh)["scenarios"]}


def test_ctlbench_scores_a_rig_of_ones_own(tmp_path):
    """leveler-ctlbench --config FILE: the thesis config given as a file of one's own
    scores as the suite's own scenario does; the model with a leak makes the
    compressor work longer at rest (it refills what leaks)."""
    own = ctlbench(["--config", BASE], tmp_path / "own")
    suite = ctlbench([], tmp_path / "suite")
    assert own["thesis-900lb"]["runs"] == suite["thesis-900lb"]["runs"]
    leak = write_config(tmp_path / "leaky.ini", {"leak": {"leak_area_m2": 6e-9}})
    leaky = ctlbench(["--config", leak], tmp_path / "leaky")
    assert set(leaky) == {"leaky", "rest-leaky-noise2"}
    # (algorithms 1 and 3; algorithm 2's compressor chatters at its charge limit either way)
    on = [r["compressor_on_s"] for r in leaky["rest-leaky-noise2"]["runs"] if r["algorithm"] != 2]
    base = [r["compressor_on_s"] for r in own["rest-900lb-noise2"]["runs"] if r["algorithm"] != 2]
    assert all(a > b + 1.0 for a, b in zip(on, base)), (on, base)


def test_the_fits_unit_box_maps_every_parameter_both_ways():
    """Every fitted parameter goes to the unit box and back unchanged, its fit bounds
    at 0 and 1; a parameter with a knee is 0 (the nominal plant) at 0 and spaced
    in ratios well above the knee: 80 to 250 ms takes as much of the box as 250 to 800 ms."""
    for e in fx.EFFECTS:
        for p in e.params:
            one = fx.Effect(e.name, e.effect_id, (p,), e.doc)
            assert fx.from_unit(one, [0.0])[p.name] == pytest.approx(p.lo, rel=1e-12, abs=0)
            assert fx.from_unit(one, [1.0])[p.name] == pytest.approx(p.hi, rel=1e-12)
            for u in np.linspace(0.0, 1.0, 11):
                v = fx.from_unit(one, [u])[p.name]
                assert fx.to_unit(one, {p.name: v})[0] == pytest.approx(u, abs=1e-12), (e.name, p.name, u)
    knees = [(e, p) for e in fx.EFFECTS for p in e.params if p.knee > 0]
    assert knees, "no parameter fitted with a knee"
    for e, p in knees:
        one = fx.Effect(e.name, e.effect_id, (p,), e.doc)
        assert fx.from_unit(one, [0.0])[p.name] == 0.0 == p.nominal
        if p.hi >= 0.8:
            u = {v: fx.to_unit(one, {p.name: v})[0] for v in (0.08, 0.25, 0.8)}
            assert u[0.25] - u[0.08] == pytest.approx(u[0.8] - u[0.25], rel=0.1), (e.name, p.name)

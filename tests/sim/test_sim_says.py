"""Issue 24: the simulator says what happened.

Each test runs the real leveler-sim (LEVELER_SIM) and checks what it writes and
prints against an independent expectation: the supervisor's own fault bits
(status.h), the config's end stops, the thesis's published cases, the sensor
span's quantisation step, and the diagnosis's refusal of another config's logs.
"""
import json
import os
import subprocess
import sys

import numpy as np
import pytest

from leveler import runlog

SIM = os.environ.get("LEVELER_SIM", "leveler-sim")
CONFIGS = os.environ.get("LEVELER_CONFIG_DIR", os.path.join(os.path.dirname(__file__), "../../host_sim/configs"))
BASE = os.path.join(CONFIGS, "thesis-900lb.ini")
IN = 0.0254
CHATTER_BIT = 1 << (8 - 1)          # fault code 8 (status.h LEVELER_FAULT_CHATTER)


def sim(*args, check=None):
    p = subprocess.run([SIM, *args], capture_output=True, text=True, timeout=300)
    if check is not None:
        assert p.returncode == check, p.stdout + p.stderr
    return p


def config(tmp_path, name, body):
    path = tmp_path / f"{name}.ini"
    path.write_text(f"[config]\ninclude = {BASE}\nname = {name}\n{body}")
    return str(path)


def resolved(path):
    return json.loads(sim("--dump-config", "--config", path, check=0).stdout)


def test_noisy_run_latches_the_chatter_fault_and_says_so(tmp_path):
    cfg = config(tmp_path, "noisy", "[sensors]\nnoise_counts = 2\n")
    log = str(tmp_path / "noisy.csv")
    p = sim("--config", cfg, "--log", log, "--fail-on-fault")
    assert p.returncode == 1, p.stdout + p.stderr
    assert "latched chatter" in p.stdout and "held safe" in p.stdout, p.stdout
    r = runlog.read(log)
    bits = np.nan_to_num(r.latched_fault_bits).astype(int)
    assert (bits & CHATTER_BIT).any()
    first = r.t_s[np.flatnonzero(bits & CHATTER_BIT)[0]]
    assert f"at {first:.2f} s" in p.stdout           # the summary's time is the log's
    latched = bits > 0
    # the outputs are safe (all off) on every row the fault is latched
    for a in runlog.ACTUATORS:
        assert not np.nansum(r.column(a)[latched]), a
    assert sim("--config", cfg, "--log", log).returncode == 0   # without --fail-on-fault


def test_quiet_run_has_no_fault_and_state_columns(tmp_path):
    log = str(tmp_path / "quiet.csv")
    p = sim("--config", BASE, "--log", log, "--fail-on-fault", check=0)
    assert "no fault latched" in p.stdout
    r = runlog.read(log)
    assert r.format_version == runlog.FORMAT_VERSION == 3
    assert not np.nansum(r.latched_fault_bits)
    assert set(np.unique(r.mode[1:])) == {1.0}                  # auto
    valid = r.sensors_valid == 1.0
    assert valid[200:].all()
    # SAFE (3) only before the sensors are valid; in band, charging, discharging after
    assert set(np.unique(r.control_state[valid])) == {0.0, 1.0, 2.0}
    assert set(np.unique(r.control_state[~valid][1:])) == {3.0}


def test_step_past_the_travel_stops_at_the_end_stop_and_warns(tmp_path):
    cfg = config(tmp_path, "step300", "[scenario]\nstep_load_lbf = 300\n")
    stops = resolved(cfg)["platform"]
    assert stops["height_min_m"] == pytest.approx(13.76 * IN)
    log = str(tmp_path / "step300.csv")
    p = sim("--config", cfg, "--log", log, check=0)
    assert "bottom end stop (13.76 in" in p.stdout, p.stdout
    r = runlog.read(log)
    assert np.min(r.true_height_m) == pytest.approx(stops["height_min_m"], abs=1e-9)
    assert np.max(r.true_height_m) <= stops["height_max_m"] + 1e-9


def test_schedule_in_lbf_is_refused_with_its_row(tmp_path):
    sched = tmp_path / "lbf.csv"
    sched.write_text("t_s,load_n\n0,900\n5,1100\n35,900\n")
    p = sim("--config", BASE, "--schedule", str(sched), "--log", str(tmp_path / "x.csv"), check=2)
    assert f"{sched}:2: load_n: 900 N is outside" in p.stderr, p.stderr
    assert "look like lbf" in p.stderr


def test_readings_beside_the_truth(tmp_path):
    log = str(tmp_path / "r.csv")
    sim("--config", BASE, "--log", log, check=0)
    r = runlog.read(log)
    sensors = resolved(BASE)["sensors"]
    lsb_m = (sensors["height_hi_m"] - sensors["height_lo_m"]) / (sensors["height_hi_counts"] - sensors["height_lo_counts"])
    d = np.abs(r.height_m[1:] - r.true_height_m[1:])
    assert 0.0 < np.max(d) <= 0.5 * lsb_m + 1e-6   # quantised to the nearest count (and the firmware's um)
    assert np.nanmax(np.abs(r.p_spring_pa[1:] - r.true_p_spring_pa[1:])) > 0.0


def test_thesis_table_only_for_a_thesis_case(tmp_path):
    env = dict(os.environ, MPLBACKEND="Agg")
    diaphragm = os.path.join(CONFIGS, "thesis-900lb-diaphragm.ini")
    log, summ = str(tmp_path / "d.csv"), str(tmp_path / "d.json")
    p = subprocess.run([SIM, "--config", diaphragm, "--algorithm", "3", "--log", log, "--summary", summ],
                       capture_output=True, text=True, env=env, timeout=300)
    assert p.returncode == 0, p.stderr
    assert "its own event figures" in p.stdout and "thesis-900lb-sim" not in p.stdout
    p = subprocess.run([SIM, "--config", diaphragm, "--algorithm", "2", "--log", log, "--summary", summ],
                       capture_output=True, text=True, env=env, timeout=300)
    assert "compared with thesis-900lb-acc112psig-exp" in p.stdout, p.stdout   # its own charge, 112 psig
    p = subprocess.run([SIM, "--config", BASE, "--log", log, "--summary", summ],
                       capture_output=True, text=True, env=env, timeout=300)
    assert "compared with thesis-900lb-sim" in p.stdout


def test_format_2_logs_still_read():
    text = ("# leveler run log, format 2\n# config: x\n# source: rig\n"
            "t_s,height_m,p_spring_pa,p_pipe_pa,p_acc_pa,load_n,compressor,spring_valve,vent_valve,acc_valve\n"
            "0,0.39751,613633,613633,,4003.4,0,0,0,0\n0.01,0.3976,613700,613702,,4003.4,1,1,0,0\n")
    r = runlog.parse(text)
    assert r.format_version == 2 and len(r) == 2
    assert np.isnan(r.latched_fault_bits).all() and np.isnan(r.true_height_m).all()


def test_diagnosis_refuses_another_configs_logs(tmp_path):
    logs = []
    for i, end in enumerate((20, 21, 22)):
        path = str(tmp_path / f"l{i}.csv")
        sim("--config", os.path.join(CONFIGS, "thesis-1000lb.ini"), "--log", path, "--end-s", str(end), check=0)
        logs.append(path)
    cmd = [sys.executable, "-m", "leveler.diagnose", "--config", BASE, "--run", logs[0], "--run", logs[1],
           "--holdout", logs[2], "--out", str(tmp_path / "out"), "--quiet"]
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert p.returncode == 2, p.stdout + p.stderr
    assert "logged config 'thesis-1000lb' is not --config's 'thesis-900lb'" in p.stderr, p.stderr
    assert not os.path.exists(tmp_path / "out")


def test_family_logs_are_the_runs_it_scores(tmp_path):
    """leveler-ctlbench-family --logs writes each run's log without changing a figure
    (family.json is the same as without --logs), and the limit's log is the limit the
    issue defines: every fill path opened at the instant the load is added."""
    fam = os.path.join(os.path.dirname(SIM), "leveler-ctlbench-family")
    out = {}
    for name, extra in (("plain", []), ("logged", ["--logs"])):
        d = tmp_path / name
        p = subprocess.run([fam, "--out", str(d), "--rigs", "1", *extra], capture_output=True, text=True,
                           timeout=300)
        assert p.returncode == 0, p.stderr
        out[name] = json.loads((d / "family.json").read_text())
    assert out["plain"] == out["logged"]
    logged = tmp_path / "logged"
    assert not list((tmp_path / "plain").glob("*.csv"))
    for who in ("rig-01-alg3", "rig-01-limit", "rig-01-commissioned-alg3", "rig-01-commissioned-limit"):
        assert (logged / f"{who}.csv").stat().st_size > 0, who
    lim = runlog.read(logged / "rig-01-limit.csv")
    added = np.flatnonzero(np.diff(lim.load_n) > 0)[0] + 1      # the first row under the heavier load
    for valve in ("compressor", "spring_valve", "acc_valve"):
        assert lim.column(valve)[added] == 1, (valve, lim.t_s[added])
    a3 = runlog.read(logged / "rig-01-alg3.csv")
    np.testing.assert_array_equal(a3.load_n, lim.load_n)         # one scenario, two controllers

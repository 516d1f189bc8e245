"""Issue 22: one command style. Every program answers --help (exit 0, the
shared layout) and --version (the top-level VERSION file), refuses an unknown
option with exit 2, and takes --opt=value as it takes --opt value. The
firmware's version register reads the same version over Modbus (pymodbus)."""
import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
VERSION = (ROOT / "VERSION").read_text()
EXIT_LINE = "exit codes: 0 done, 1 the job failed, 2 bad input"
CONFIG = str(ROOT / "host_sim" / "configs" / "thesis-900lb.ini")
PY = os.environ.get("LEVELER_PYTHON", sys.executable)


def c_program(name):
    path = os.environ.get("LEVELER_BIN_" + name.upper().replace("-", "_"), "")
    if not path:
        pytest.skip(f"{name} not built")
    return [path]


# name -> how to run it, and the shared options its help must name
PROGRAMS = {
    "leveler-sim": (lambda: c_program("leveler-sim"), ["--config", "--log", "--quiet"]),
    "leveler-rig": (lambda: c_program("leveler-rig"), ["--config"]),
    "leveler-plant-server": (lambda: c_program("leveler-plant-server"), ["--config"]),
    "leveler-schedule-run": (lambda: c_program("leveler-schedule-run"), []),
    "leveler-mbaps": (lambda: c_program("leveler-mbaps"), ["--config"]),
    "leveler-ctlbench": (lambda: c_program("leveler-ctlbench"), ["--out", "--quiet"]),
    "leveler-ctlbench-family": (lambda: c_program("leveler-ctlbench-family"), ["--out", "--configs", "--rigs"]),
    "leveler-sim-bench": (lambda: c_program("leveler-sim-bench"), ["--config"]),
    "leveler-diagnose": (lambda: [str(ROOT / "scripts" / "leveler-diagnose")], ["--config", "--out", "--quiet"]),
    "leveler-blindtest": (lambda: [str(ROOT / "scripts" / "leveler-blindtest")], ["--out", "--log-kind", "--json"]),
    "leveler-monitor": (lambda: [str(ROOT / "scripts" / "leveler-monitor")], ["--host", "--port"]),
    "python -m leveler.report": (lambda: [PY, "-m", "leveler.report"], ["--config", "--log"]),
}


C_PROGRAMS = [n for n in PROGRAMS if not n.startswith("python")
              and n not in ("leveler-diagnose", "leveler-blindtest", "leveler-monitor")]


def run(argv, **kw):
    env = dict(os.environ, PYTHONPATH=str(ROOT / "scripts"), LEVELER_PYTHON=PY, MPLBACKEND="Agg")
    return subprocess.run(argv, capture_output=True, text=True, timeout=120, env=env, **kw)


@pytest.mark.parametrize("name", PROGRAMS)
def test_help_version_and_unknown_option(name):
    argv, shared = PROGRAMS[name][0](), PROGRAMS[name][1]
    h = run(argv + ["--help"])
    assert h.returncode == 0, h.stderr
    assert h.stdout.startswith(f"usage: {name}"), h.stdout[:200]
    assert EXIT_LINE in h.stdout and "--version" in h.stdout
    for opt in shared:
        assert re.search(rf"^\s+(-\w, )?{opt}\b", h.stdout, re.M), f"{name} --help: no line for {opt}"
    v = run(argv + ["--version"])
    assert (v.returncode, v.stdout, v.stderr) == (0, f"{name} {VERSION}", "")
    bad = run(argv + ["--no-such-option"])
    assert bad.returncode == 2 and bad.stdout == ""
    # argparse names a missing required option first; the C programs name the unknown one
    assert "--no-such-option" in bad.stderr or (name not in C_PROGRAMS and "error:" in bad.stderr), bad.stderr


def test_c_help_layout_one_line_per_option():
    """Every option line of a C program's help starts with two spaces and --name (cli.h's layout)."""
    out = run(c_program("leveler-plant-server") + ["--help"]).stdout
    lines = out.split("options (--opt VALUE or --opt=VALUE):\n")[1].split("\n\n")[0].splitlines()
    names = [l.split()[0] for l in lines if l.startswith("  -")]
    assert names == ["--config", "--address", "--port", "--port-file", "--clock", "--max-seconds", "--schedule", "-h,",
                     "--version"]


def test_sim_equals_form_gives_the_same_config():
    sim = c_program("leveler-sim")
    a = run(sim + ["--dump-config", "--config", CONFIG])
    b = run(sim + ["--dump-config", f"--config={CONFIG}"])
    assert a.returncode == 0 and a.stdout == b.stdout
    assert json.loads(a.stdout)["config"]["name"] == "thesis-900lb"


def test_sim_bad_values_are_exit_2_naming_the_option(tmp_path):
    sim = c_program("leveler-sim")
    for arg, text in (("--algorithm=4", "--algorithm: '4'"), ("--end-s=abc", "--end-s: 'abc'"),
                      ("--units=furlongs", "--units: 'furlongs'")):
        p = run(sim + [f"--config={CONFIG}", f"--log={tmp_path / 'r.csv'}", arg])
        assert p.returncode == 2 and text in p.stderr, (arg, p.stderr)
    p = run(sim + ["--config"])
    assert p.returncode == 2 and "needs a value" in p.stderr


def test_sim_log_with_equals_and_version_header(tmp_path):
    log = tmp_path / "run.csv"
    p = run(c_program("leveler-sim") + [f"--config={CONFIG}", f"--log={log}", "--end-s=2", "--quiet"])
    assert p.returncode == 0, p.stderr
    head = log.read_text().splitlines()[:4]
    assert head[3] == f"# version: {VERSION.strip()}"


def test_rig_check_with_equals():
    p = run(c_program("leveler-rig") + [f"--config={ROOT / 'boards' / 'linux-rig' / 'rig.ini'}", "--check"])
    assert p.returncode == 0 and p.stdout.endswith("rig.ini: ok\n")
    p = run(c_program("leveler-rig") + ["--check"])
    assert p.returncode == 2 and "--config" in p.stderr


def test_plant_server_with_equals(tmp_path):
    port_file = tmp_path / "port"
    p = run(c_program("leveler-plant-server") + [f"--config={CONFIG}", "--port=0", f"--port-file={port_file}",
                                                  "--clock=realtime", "--max-seconds=0.3"])
    assert p.returncode == 0, p.stderr
    assert 0 < int(port_file.read_text()) < 65536
    p = run(c_program("leveler-plant-server") + [f"--config={CONFIG}", "--port=70000"])
    assert p.returncode == 2 and "--port: '70000'" in p.stderr


def test_schedule_run_with_equals(tmp_path):
    p = run(c_program("leveler-schedule-run") + [f"--schedule={tmp_path / 'none.csv'}", "--port=1502"])
    assert p.returncode == 2 and "none.csv" in p.stderr    # the file was taken from --schedule=
    p = run(c_program("leveler-schedule-run") + [f"--schedule={tmp_path / 'none.csv'}", "--unit=300"])
    assert p.returncode == 2 and "--unit: '300'" in p.stderr


def test_ctlbench_out_with_equals_follows_the_umask(tmp_path):
    out = tmp_path / "card"
    p = run(c_program("leveler-ctlbench") + [f"--out={out}", "--short", "--no-plots", "--quiet"],
            preexec_fn=lambda: os.umask(0o022))
    assert p.returncode == 0, p.stderr
    assert p.stderr == ""                                   # --quiet: no progress lines
    assert json.loads((out / "scorecard.json").read_text())["scenarios"]
    assert (out.stat().st_mode & 0o777) == 0o755


def test_sim_bench_config_with_equals(tmp_path):
    p = run(c_program("leveler-sim-bench") + [f"--config={tmp_path / 'none.ini'}"])
    assert p.returncode == 2 and "none.ini" in p.stderr


def test_report_summary_and_plot_follow_the_umask(tmp_path):
    log = tmp_path / "run.csv"
    p = run(c_program("leveler-sim") + [f"--config={CONFIG}", f"--log={log}", "--quiet"],
            preexec_fn=lambda: os.umask(0o002))
    assert p.returncode == 0 and (log.stat().st_mode & 0o777) == 0o664     # the run log too
    for mask, mode in ((0o022, 0o644), (0o002, 0o664)):
        s, png = tmp_path / f"s{mask}.json", tmp_path / f"p{mask}.png"
        p = run([PY, "-m", "leveler.report", f"--log={log}", f"--summary={s}", f"--plot={png}", "--units=si"],
                preexec_fn=lambda m=mask: os.umask(m))
        assert p.returncode == 0, p.stderr
        assert (s.stat().st_mode & 0o777, png.stat().st_mode & 0o777) == (mode, mode)
        assert f"(leveler {VERSION.strip()}; log written by {VERSION.strip()})" in p.stdout


def test_diagnose_equals_form_reaches_the_input_check(tmp_path):
    p = run([str(ROOT / "scripts" / "leveler-diagnose"), "--config=thesis-900lb", f"--out={tmp_path / 'o'}",
             f"--features={tmp_path / 'none.json'}"])
    assert p.returncode == 2 and "none.json" in p.stderr


def test_monitor_exit_codes(tmp_path):
    """leveler-monitor: bad options and a missing register map are 2, no Modbus peer is 1."""
    import socket
    monitor = [str(ROOT / "scripts" / "leveler-monitor")]
    p = run(monitor + ["--rate=20"])
    assert p.returncode == 2 and "--rate: 20" in p.stderr
    p = run(monitor + [f"--regmap={tmp_path / 'none.json'}"])
    assert p.returncode == 2 and "none.json" in p.stderr
    with socket.socket() as s:          # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    p = run(monitor + [f"--port={port}", "--http-port=0"])
    assert p.returncode == 1 and f"127.0.0.1:{port}: no answer" in p.stderr


def test_firmware_version_register_over_modbus(tmp_path):
    """Input register firmware_version (registers.json) = major*10000 + minor*100 + patch of VERSION."""
    if not os.environ.get("LEVELER_RIG"):
        pytest.skip("leveler-rig not built")
    sys.path.insert(0, str(ROOT / "tests" / "rig" / "py"))
    import rigproc as rp
    reg = next(r for r in json.loads((ROOT / "firmware" / "regmap" / "registers.json").read_text())["registers"]
               if r["name"] == "firmware_version")
    major, minor, patch = (int(x) for x in VERSION.strip().split("."))
    plant = rp.Plant(tmp_path)
    try:
        rig = rp.Rig(tmp_path, plant).start()
        try:
            c = rig.client()
            value = c.read_input_registers(reg["address"], count=1).registers[0]
            c.close()
        finally:
            rig.stop()
    finally:
        plant.stop()
    assert reg["table"] == "input" and value == major * 10000 + minor * 100 + patch

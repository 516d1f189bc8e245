"""Issue 23, item 8: outputs safe when the service's process is gone.

However leveler-rig ended (SIGKILL, a crash, systemd's watchdog kill, a
failed ExecStartPre=--check), the unit's ExecStopPost= runs
`leveler-rig --safe-outputs --config FILE`, which takes the outputs, drives
them de-energised and exits. Here the unit's own ExecStopPost= command line
(binary and config path put in for this test) runs against the module a
SIGKILLed rig left charging, with no module watchdog to help; and the unit
passes `systemd-analyze verify`."""

import os
import re
import shlex
import shutil
import signal
import subprocess
import time
from pathlib import Path

import pytest

import rigproc as rp
from test_outputs_safe import coils, start_charging

UNIT = Path(__file__).resolve().parents[3] / "boards" / "linux-rig" / "leveler-rig.service"
INSTALLED = "/usr/local/bin/leveler-rig"


def exec_stop_post(config: Path):
    lines = re.findall(r"^ExecStopPost=(.*)$", UNIT.read_text(), re.M)
    assert len(lines) == 1, "the unit needs one ExecStopPost= line"
    argv = shlex.split(lines[0].replace(INSTALLED, rp.RIG).replace("/etc/leveler/rig.ini", str(config)))
    assert argv[0] == rp.RIG and "--safe-outputs" in argv
    return argv


def test_exec_stop_post_drives_outputs_safe_after_sigkill(tmp_path, plant):
    module = plant.client()
    rig = rp.Rig(tmp_path, plant).start()  # no module watchdog: nothing else would switch them off
    try:
        start_charging(rig, module)
        os.kill(rig.proc.pid, signal.SIGKILL)
        rig.proc.wait()
        time.sleep(0.3)
        assert coils(module)[:2] == [True, True], "the control case: a dead rig leaves the coils on"
        t0 = time.monotonic()
        done = subprocess.run(exec_stop_post(rig.config_path), capture_output=True, text=True, timeout=20)
        ms = (time.monotonic() - t0) * 1000
        print(f"--safe-outputs: exit {done.returncode} after {ms:.0f} ms: {done.stderr.strip()}")
        assert done.returncode == 0, done.stderr
        assert coils(module) == [False] * 4
    finally:
        rig.stop()
        module.close()


def test_safe_outputs_fails_loudly_without_the_module(tmp_path, plant):
    rig = rp.Rig(tmp_path, plant, overrides={"sensors": {"port": 1, "timeout_ms": 5}})
    done = subprocess.run([rp.RIG, "--safe-outputs", "--config", str(rig.config_path)], capture_output=True,
                          text=True, timeout=30)
    assert done.returncode == 1
    assert "--safe-outputs" in done.stderr and str(rig.config_path) in done.stderr


def test_unit_verifies(tmp_path):
    analyze = shutil.which("systemd-analyze")
    if analyze is None:
        pytest.skip("systemd-analyze is not installed (Debian package systemd)")
    unit = tmp_path / "leveler-rig.service"
    unit.write_text(UNIT.read_text().replace(INSTALLED, rp.RIG))
    done = subprocess.run([analyze, "verify", "--man=no", str(unit)], capture_output=True, text=True, timeout=60)
    print(done.stdout + done.stderr)
    assert done.returncode == 0 and "leveler-rig.service" not in done.stderr, done.stderr

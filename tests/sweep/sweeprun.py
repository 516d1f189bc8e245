"""Helpers of the leveler-sweep tests: a study file, the command, the table."""
import csv
import os
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
CONFIGS = ROOT / "host_sim" / "configs"


def write_study(folder, charges, volumes, algorithms=(2, 3), end_s=None, name="t"):
    """A tube-accumulator study over charge x volume x algorithm (900 lb)."""
    lines = ["[study]", f'name = "{name}"', f'configs = ["{CONFIGS / "thesis-900lb-tube.ini"}"]',
             f"algorithms = {list(algorithms)}"]
    if end_s is not None:
        lines.append(f"end_s = {end_s}")
    lines += ["[vary]", f'"accumulator.charge_psig" = {list(charges)}', f'"accumulator.volume_in3" = {list(volumes)}']
    path = Path(folder) / f"{name}.toml"
    path.write_text("\n".join(lines) + "\n")
    return path


def command(study, out, *extra):
    return [sys.executable, "-m", "leveler.sweep", "--study", str(study), "--out", str(out), "--no-plots", *extra]


def run(study, out, *extra, timeout=120):
    p = subprocess.run(command(study, out, *extra), capture_output=True, text=True, timeout=timeout)
    assert p.returncode == 0, f"exit {p.returncode}\n{p.stderr[-3000:]}"
    return p


def start(study, out, *extra):
    """The sweep as a process a test may kill: its temporary folders go under the test's
    own folder (TMPDIR), since a process killed mid-point cannot remove its own."""
    env = dict(os.environ, TMPDIR=str(Path(out).parent))
    return subprocess.Popen(command(study, out, *extra), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=env)


def rows(out):
    with open(Path(out) / "sweep.csv", newline="") as fh:
        return list(csv.DictReader(fh))


def wait_rows(out, n, proc, timeout=60):
    """Waits until sweep.csv holds at least n rows (whole lines) while proc runs."""
    path, deadline = Path(out) / "sweep.csv", time.monotonic() + timeout
    while time.monotonic() < deadline:
        if path.exists() and path.read_bytes().count(b"\n") - 1 >= n:
            return
        assert proc.poll() is None, f"the sweep ended before {n} rows: {proc.communicate()[1][-2000:]}"
        time.sleep(0.02)
    raise AssertionError(f"no {n} rows in {path} after {timeout} s")

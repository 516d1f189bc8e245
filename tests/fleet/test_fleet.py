"""leveler-diagnose --fleet: a fleet of 3 rigs with different effects (leak,
thermal, none: the blind test's truth generator, seed 1), one diagnosis each
as a task on a 2-worker Dask LocalCluster; each rig gets its own verdict, the
fleet table and the page link each rig's report; run again, the fleet keeps
what it has and diagnoses only the rig whose logs changed."""
import csv
import os
import subprocess
import sys
from pathlib import Path

from leveler.diagnose import blindtest
from leveler.diagnose.model import make_simulator

ROOT = Path(__file__).resolve().parents[2]
TRUTH = {"rig-leak": "leak", "rig-thermal": "thermal", "rig-sound": "none"}


def make_fleet(top):
    sim = make_simulator()
    for rig, effect in TRUTH.items():
        folder = top / rig
        logs = folder / "truth"
        logs.mkdir(parents=True)
        blindtest.generate_case(sim, effect, 1, str(logs))
        for src, dst in (("cal1", "run1"), ("cal2", "run2"), ("hold", "holdout")):
            os.rename(logs / f"{src}.csv", folder / f"{dst}.csv")
        os.unlink(logs.parent / "rig.ini")          # the truth's rig config: not the rig's model
        (folder / "thesis-900lb.ini").write_text(
            f"[config]\ninclude = {ROOT / 'host_sim' / 'configs' / 'thesis-900lb.ini'}\n")


def test_three_rigs_three_verdicts(tmp_path):
    make_fleet(tmp_path / "fleet")
    out = tmp_path / "out"
    p = subprocess.run([sys.executable, "-m", "leveler.diagnose", "--fleet", str(tmp_path / "fleet"), "--out", str(out),
                        "--workers", "2", "--dashboard", ":0", "--fast", "--effects", "leak,thermal,valve_dynamics"],
                       capture_output=True, text=True, timeout=170)
    assert p.returncode == 0, p.stderr[-3000:]
    assert "3 rigs on 2 worker threads; dashboard http://" in p.stderr
    with open(out / "fleet.csv", newline="") as fh:
        rows = {r["rig"]: r for r in csv.DictReader(fh)}
    assert sorted(rows) == sorted(TRUTH)
    for rig, effect in TRUTH.items():
        assert rows[rig]["effect"] == effect, rows[rig]
        assert rows[rig]["error"] == "" and rows[rig]["confidence"]
        assert (out / rig / "diagnosis.json").exists() and (out / rig / "report.html").exists()
    assert float(rows["rig-leak"]["shrink_pct"]) > 50 and float(rows["rig-thermal"]["shrink_pct"]) > 50
    page = (out / "index.html").read_text()
    assert all(f'href="{rig}/report.html"' in page for rig in TRUTH)
    resume_keeps_what_is_done(tmp_path / "fleet", out, rows)


def resume_keeps_what_is_done(fleet, out, rows):
    """Run again: every rig kept from its stamp (no diagnosis rerun, same table);
    one rig's held-out log changed: that rig alone is diagnosed again."""
    before = {rig: (out / rig / "diagnosis.json").stat().st_mtime_ns for rig in TRUTH}
    (fleet / "rig-sound" / "holdout.csv").write_bytes((fleet / "rig-sound" / "run2.csv").read_bytes())
    p = subprocess.run([sys.executable, "-m", "leveler.diagnose", "--fleet", str(fleet), "--out", str(out),
                        "--serial", "--fast", "--effects", "leak,thermal,valve_dynamics"],
                       capture_output=True, text=True, timeout=170)
    assert p.returncode == 0, p.stderr[-3000:]
    assert "2 rig(s) already diagnosed from the same inputs, kept (rig-leak, rig-thermal" in p.stderr
    after = {rig: (out / rig / "diagnosis.json").stat().st_mtime_ns for rig in TRUTH}
    assert after["rig-leak"] == before["rig-leak"] and after["rig-thermal"] == before["rig-thermal"]
    assert after["rig-sound"] != before["rig-sound"]
    with open(out / "fleet.csv", newline="") as fh:
        again = {r["rig"]: r for r in csv.DictReader(fh)}
    for rig in ("rig-leak", "rig-thermal"):
        assert again[rig] == rows[rig]


def test_a_folder_that_is_not_a_rig_is_bad_input(tmp_path):
    (tmp_path / "fleet" / "rig-1").mkdir(parents=True)
    (tmp_path / "fleet" / "rig-1" / "run1.csv").write_text("")
    p = subprocess.run([sys.executable, "-m", "leveler.diagnose", "--fleet", str(tmp_path / "fleet"),
                        "--out", str(tmp_path / "out"), "--serial"], capture_output=True, text=True, timeout=60)
    assert p.returncode == 2 and "rig-1/ needs one *.ini (has 0)" in p.stderr

"""python -m leveler.report: table, JSON, PNG, errors."""

import json
import os
import subprocess
import sys

import pytest

import synth
from leveler import events, report, runlog, thesis

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


@pytest.fixture(scope="module")
def run_csv(tmp_path_factory):
    path = tmp_path_factory.mktemp("logs") / "run.csv"
    runlog.write(path, synth.make_log(height_noise_m=0.3e-3, p_noise_pa=2000.0,
                                      height_quantum_m=0.08e-3))
    return path


def test_summary_json_and_table(run_csv, tmp_path, capsys):
    out = tmp_path / "s.json"
    assert report.main(["--log", str(run_csv), "--summary", str(out)]) == 0
    data = json.loads(out.read_text())
    assert tuple(data) == events.SUMMARY_KEYS
    assert data["time_stuck_bottom_s"] == pytest.approx(16.0, abs=0.15)
    text = capsys.readouterr().out
    assert "compared with thesis-900lb-sim" in text
    version = open(os.path.join(ROOT, "VERSION")).read().strip()
    assert f"(leveler {version}; log written by a version before 0.6.0)" in text   # synth logs carry none
    # lowest height: run 14.53 in beside the published 14.53 in.
    line = next(l for l in text.splitlines() if l.startswith("lowest height"))
    assert "14.53" in line and " in " in line


def test_si_units_and_explicit_case(run_csv, capsys):
    assert report.main(["--log", str(run_csv), "--units", "si", "--compare", "thesis-1000lb-exp"]) == 0
    text = capsys.readouterr().out
    line = next(l for l in text.splitlines() if l.startswith("time stuck at the bottom"))
    cells = line.split()
    run, pub, diff = float(cells[-3]), float(cells[-2]), float(cells[-1])
    assert pub == 17.0 and diff == pytest.approx(run - pub, abs=0.011)


def test_plot_writes_a_png(run_csv, tmp_path):
    png = tmp_path / "r.png"
    cfg = tmp_path / "c.ini"
    cfg.write_text("[controller]\nband_lower_in = 15.6\nband_upper_in = 15.8\n")
    assert report.main(["--log", str(run_csv), "--plot", str(png), "--config", str(cfg)]) == 0
    data = png.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 20000
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []


def test_bad_log_exits_2_and_writes_nothing(tmp_path):
    bad = tmp_path / "bad.csv"
    bad.write_text("# leveler run log, format 2\n" + ",".join(runlog.BASE_COLUMNS) + "\n"
                   "0.0,15.65,89,89,,900,0,0,0,0\n")
    out = tmp_path / "s.json"
    env = dict(os.environ, PYTHONPATH=os.path.join(ROOT, "scripts"), MPLBACKEND="Agg")
    proc = subprocess.run([sys.executable, "-m", "leveler.report", "--log", str(bad),
                           "--summary", str(out)], capture_output=True, text=True, env=env)
    assert proc.returncode == 2
    assert f"{bad}:3: column height_m" in proc.stderr and "inches" in proc.stderr
    assert not out.exists()


def test_missing_log_file(tmp_path, capsys):
    assert report.main(["--log", str(tmp_path / "nope.csv")]) == 2
    assert "nope.csv: cannot read" in capsys.readouterr().err

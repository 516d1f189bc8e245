"""leveler-sweep's parts against independent expectations: the study's ranges,
a point's config as the C loader resolves it, the control figures of a log
built with known answers, and the command's bad-input errors (exit 2)."""
import subprocess
import sys

import numpy as np
import pytest

from leveler import config, runlog
from leveler.sweep import figures, study
from sweeprun import CONFIGS, command, rows, run, write_study


def test_ranges_expand_as_written():
    assert study.expand_range({"from": 90, "to": 130, "step": 10}, "x") == [90, 100, 110, 120, 130]
    assert study.expand_range({"from": 1.0, "to": 1.4, "step": 0.1}, "x") == [1.0, 1.1, 1.2, 1.3, 1.4]
    assert study.expand_range({"from": 0, "to": 1, "count": 5}, "x") == [0, 0.25, 0.5, 0.75, 1]
    with pytest.raises(study.StudyError, match="does not go"):
        study.expand_range({"from": 1, "to": 0, "step": 1}, "x")


def test_a_point_is_the_base_with_its_keys_as_the_c_loader_resolves_them(tmp_path):
    s = study.load(write_study(tmp_path, charges=[100, 120], volumes=[25, 50]))
    points = s.points()
    assert len(points) == 2 * 2 * 2 and len({p.point_id for p in points}) == 8
    p = next(p for p in points if dict(p.settings) == {"accumulator.charge_psig": 120, "accumulator.volume_in3": 50}
             and p.algorithm == 3)
    ini = tmp_path / "p.ini"
    ini.write_text(p.ini_text())
    got = config.resolved(str(ini))
    base = config.resolved(str(CONFIGS / "thesis-900lb-tube.ini"))
    ambient = got["ambient"]["pressure_pa"]
    assert got["accumulator"]["charge_pa"] == pytest.approx(120 * 6894.757293168 + ambient, rel=1e-9)
    assert got["accumulator"]["volume_m3"] == pytest.approx(50 * 0.0254 ** 3, rel=1e-12)
    for section in ("spring", "platform", "controller", "hysteresis"):     # the rest is the base's
        assert got[section] == base[section]


def _known_log():
    """Band 0.40..0.41 m; +1000 N at 2 s; the platform drops to 0.39, climbs
    back (in the band at 4.8 s), shoots to 0.415 at 6 s (0.005 m over), settles."""
    t = np.round(np.arange(0.0, 20.0 + 1e-9, 0.01), 6)
    h = np.interp(t, [0, 2, 2.5, 4, 6, 7, 20], [0.405, 0.405, 0.39, 0.39, 0.415, 0.405, 0.405])
    comp = ((t >= 2.5) & (t < 5.5)).astype(float)
    vent = ((t >= 6.0) & (t < 6.5)).astype(float)
    valve = ((t >= 2.5) & (t < 6.5)).astype(float)
    faults = np.where(t >= 19.0, 128.0, 0.0)
    return runlog.RunLog.from_arrays(t, h, np.where(t >= 2.0, 5000.0, 4000.0), p_spring_pa=6e5, compressor=comp,
                                     spring_valve=valve, vent_valve=vent, acc_valve=0.0, true_height_m=h,
                                     latched_fault_bits=faults)


def test_control_figures_of_a_log_with_known_answers():
    got = figures.control_figures(_known_log(), 0.40, 0.41)
    assert got["overshoot_m"] == pytest.approx(0.005, abs=1e-9)
    assert got["switchings"] == 4            # 2.5 s (compressor, valve), 5.5, 6.0, 6.5 (vent, valve)
    assert got["compressor_on_s"] == pytest.approx(3.0, abs=1e-9)
    assert got["vent_open_s"] == pytest.approx(0.5, abs=1e-9)
    # below 0.40 from 2.1667 to 4.8 s, above 0.41 from 5.6 to 6.5 s
    assert got["outside_band_s"] == pytest.approx((4.8 - 2.0 - 1 / 6) + 0.9, abs=0.02)
    assert got["latched_fault_bits"] == 128


def test_no_overshoot_when_the_platform_enters_the_band_and_stays():
    log = _known_log()
    log.true_height_m = np.minimum(log.true_height_m, 0.4099)
    assert figures.control_figures(log, 0.40, 0.41)["overshoot_m"] == 0.0


def _bad(argv):
    p = subprocess.run(argv, capture_output=True, text=True, timeout=60)
    assert p.returncode == 2, p.stderr
    return p.stderr


def test_bad_input_exits_2_with_the_loaders_words(tmp_path):
    s = write_study(tmp_path, charges=[100], volumes=[25])
    s.write_text(s.read_text().replace("volume_in3", "volume_inch3"))
    assert "volume_inch3" in _bad(command(s, tmp_path / "o1", "--serial"))
    s.write_text(s.read_text().replace("volume_inch3", "volume_in3").replace("[vary]", "[varry]"))
    assert "unknown table [varry]" in _bad(command(s, tmp_path / "o2", "--serial"))
    good = write_study(tmp_path, charges=[100], volumes=[25], name="good")
    (tmp_path / "o3").mkdir()
    (tmp_path / "o3" / "notes.txt").write_text("mine")
    assert "did not write" in _bad(command(good, tmp_path / "o3", "--serial"))
    other = write_study(tmp_path, charges=[100], volumes=[25], name="other", algorithms=[2])
    other.write_text(other.read_text().replace('"accumulator.volume_in3"', '"pipe.volume_in3"'))
    run(good, tmp_path / "o4", "--serial")
    assert "not this study's" in _bad(command(other, tmp_path / "o4", "--serial"))


def test_help_and_version():
    p = subprocess.run([sys.executable, "-m", "leveler.sweep", "--help"], capture_output=True, text=True)
    assert p.returncode == 0 and "--scheduler ADDRESS" in p.stdout and "exit codes" in p.stdout
    p = subprocess.run([sys.executable, "-m", "leveler.sweep", "--version"], capture_output=True, text=True)
    assert p.returncode == 0 and p.stdout.startswith("leveler-sweep ")


def test_a_later_point_out_of_range_gets_the_loaders_message_and_exit_1(tmp_path):
    s = write_study(tmp_path, charges=[112, 500], volumes=[50], algorithms=[2])
    p = subprocess.run(command(s, tmp_path / "out", "--serial"), capture_output=True, text=True, timeout=60)
    assert p.returncode == 1, p.stderr
    table = {r["accumulator.charge_psig"]: r for r in rows(tmp_path / "out")}
    assert table["112"]["error"] == "" and table["112"]["time_return_after_step_s"]
    assert table["500"]["error"].startswith("point.ini:") and "charge_psig = 500: out of range" in table["500"]["error"]
    assert table["500"]["time_return_after_step_s"] == "" and "charge_psig = 500: out of range" in p.stderr


def test_shipped_studies_by_name():
    s = study.load(study.find("appendix-a"))
    assert len(s.points()) == 6 and s.keys == ["ambient.polytropic_exponent"]
    assert [len(study.load(study.find(n)).points()) for n in ("accumulator", "accumulator-diaphragm")] == [100, 10]
    with pytest.raises(study.StudyError, match="known: accumulator, accumulator-diaphragm, appendix-a"):
        study.find("no-such-study")

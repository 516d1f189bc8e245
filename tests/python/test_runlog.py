"""leveler.runlog: round trip, and each malformed log names its line."""

import math

import numpy as np
import pytest

import synth
from leveler import runlog

HEADER = ",".join(runlog.BASE_COLUMNS)      # format 2's: still read
TOP = "# leveler run log, format 2\n# config: thesis-900lb\n# source: rig\n" + HEADER + "\n"
# Format 1 (before the valves got their one name): still read.
TOP_FORMAT1 = ("# leveler run log, format 1\n# config: thesis-900lb\n# source: rig\n"
               "t_s,height_m,p_spring_pa,p_pipe_pa,p_acc_pa,load_n,compressor,solenoid,vent,acc_valve\n")
ROW = "0.00,0.3975,613633,613633,,4003.4,0,0,0,0\n"


def write(tmp_path, text, name="run.csv"):
    p = tmp_path / name
    p.write_text(text)
    return p


def rows(n, t0=0.0, dt=0.01, height="0.3975", p="613633", load="4003.4"):
    return "".join(f"{t0 + i * dt:.2f},{height},{p},{p},,{load},0,1,0,\n" for i in range(n))


def test_round_trip_is_exact(tmp_path):
    log = synth.make_log(height_noise_m=0.3e-3, p_noise_pa=2000.0, end=3.0)
    log.p_pipe_pa[5] = np.nan           # an unmeasured cell
    log.vent_valve[7] = np.nan                 # an unknown actuator state
    log.meta["operator"] = "bench 2"
    path = tmp_path / "r.csv"
    runlog.write(path, log)
    back = runlog.read(path)
    for c in runlog.COLUMNS:
        np.testing.assert_array_equal(back.column(c), log.column(c), err_msg=c)
    assert (back.config, back.source, back.format_version) == ("thesis-900lb", "sim", 3)
    assert back.meta == {"operator": "bench 2"}
    text = path.read_text().splitlines()
    assert text[0] == "# leveler run log, format 3" and text[4] == ",".join(runlog.COLUMNS)


def test_reads_c_writer_style_and_empty_cells(tmp_path):
    # As host_sim/runlog/runlog.c writes it: %.6f time, %.9g values, empty cells.
    p = write(tmp_path, TOP + "0.000000,0.39751,613633.1,,,4003.4,1,1,0,\n"
                              "0.010000,0.397515,613700,,,4003.4,1,,0,\n")
    log = runlog.read(p)
    assert log.source == "rig" and log.config == "thesis-900lb"
    assert math.isnan(log.p_pipe_pa[0]) and math.isnan(log.acc_valve[1])
    assert math.isnan(log.spring_valve[1]) and log.spring_valve[0] == 1.0
    assert log.height_m[1] == pytest.approx(0.397515)


def test_reads_format_1_with_its_valve_names(tmp_path):
    p = write(tmp_path, TOP_FORMAT1 + "0.000000,0.39751,613633.1,,,4003.4,1,1,0,\n"
                                      "0.010000,0.397515,613700,,,4003.4,1,0,1,\n")
    log = runlog.read(p)
    assert log.format_version == 1
    np.testing.assert_array_equal(log.spring_valve, [1.0, 0.0])
    np.testing.assert_array_equal(log.vent_valve, [0.0, 1.0])
    with pytest.raises(runlog.RunLogError) as err:       # format 1 with format 2's names
        runlog.read(write(tmp_path, TOP_FORMAT1.replace("solenoid,vent", "spring_valve,vent_valve")
                          + ROW, "mixed.csv"))
    assert str(err.value).startswith(f"{tmp_path / 'mixed.csv'}:4:") and "solenoid" in str(err.value)


@pytest.mark.parametrize("text, line, words", [
    ("# leveler run log, format 4\n" + HEADER + "\n" + ROW, 1, "unknown format version 4"),
    ("# config: x\n" + HEADER + "\n" + ROW, 1, "no format line"),
    (TOP.replace(",acc_valve", "") + ROW, 4, "missing column(s) acc_valve"),
    (TOP.replace("acc_valve", "acc_valve,extra") + ROW, 4, "unknown column(s) 'extra'"),
    (TOP + ROW + "0.01,0.3975,613633,613633,,4003.4,0,0,0\n", 6, "9 cells, expected 10"),
    (TOP + ROW + "0.01,0.3975,613633,613633,,4003.4,0,0,0,0,9\n", 6, "extra cells"),
    (TOP + ROW + "0.01,0.39x5,613633,613633,,4003.4,0,0,0,0\n", 6, "column height_m: '0.39x5' is not a number"),
    (TOP + ROW + "0.00,0.3975,613633,613633,,4003.4,0,0,0,0\n", 6, "column t_s: time 0.00 does not increase"),
    (TOP + ROW + "0.01,0.3975,613633,613633,,4003.4,0,2,0,0\n", 6, "column spring_valve: actuator state '2' is not 0 or 1"),
    (TOP_FORMAT1 + ROW + "0.01,0.3975,613633,613633,,4003.4,0,2,0,0\n", 6,
     "column solenoid: actuator state '2' is not 0 or 1"),
    (TOP + ROW + "0.01,,613633,613633,,4003.4,0,0,0,0\n", 6, "column height_m: empty cell"),
    (TOP + ROW + "0.01,0.3975,nan,613633,,4003.4,0,0,0,0\n", 6, "not a finite number"),
    (TOP, 5, "no data rows"),
    (TOP.replace("source: rig", "source: bench") + ROW, None, "neither 'sim' nor 'rig'"),
])
def test_malformed_logs_name_file_line_and_problem(tmp_path, text, line, words):
    p = write(tmp_path, text)
    with pytest.raises(runlog.RunLogError) as err:
        runlog.read(p)
    msg = str(err.value)
    assert err.value.line == line
    prefix = f"{p}:{line}: " if line is not None else f"{p}: "
    assert msg.startswith(prefix), msg
    assert words in msg, msg


@pytest.mark.parametrize("column, kwargs, first_line, words", [
    ("height_m", dict(height="15.65"), 5, "look like inches"),
    ("height_m", dict(height="397.5"), 5, "look like millimetres"),
    ("p_spring_pa", dict(p="89.0"), 5, "absolute psi (psia)"),
    ("p_spring_pa", dict(p="74.3"), 5, "absolute psi (psia)"),
    ("p_spring_pa", dict(p="512.3"), 5, "kPa"),
    ("p_spring_pa", dict(p="512300"), None, None),            # plausible absolute Pa
    ("load_n", dict(load="-900"), 5, "not plausible loads"),
])
def test_units_detector(tmp_path, column, kwargs, first_line, words):
    p = write(tmp_path, TOP + rows(20, **kwargs))
    if words is None:
        runlog.read(p)
        return
    with pytest.raises(runlog.RunLogError) as err:
        runlog.read(p)
    assert err.value.line == first_line
    assert f"column {column}: " in str(err.value) and words in str(err.value), str(err.value)


def test_units_detector_gauge_pressures():
    # 60..75 psig: gauge psi; 400..500 kPa gauge with a vented 0: gauge kPa;
    # 4e5..5e5 Pa gauge with vented near-zero readings: gauge Pa.
    assert "gauge psi" in runlog.check_units("p_spring_pa", np.r_[np.linspace(60, 75, 50), 0.5])
    assert "gauge kPa" in runlog.check_units("p_spring_pa", np.r_[np.linspace(400, 500, 50), 3.0])
    assert "gauge Pa" in runlog.check_units("p_spring_pa", np.r_[np.linspace(4e5, 5e5, 50), 1e3])
    assert runlog.check_units("p_spring_pa", np.linspace(5e5, 7e5, 50)) is None
    assert runlog.check_units("height_m", np.linspace(0.36, 0.45, 50)) is None
    # An outlier or two does not decide: the median does.
    assert runlog.check_units("height_m", np.r_[np.linspace(0.36, 0.45, 50), 15.0]) is None


def test_unit_check_can_be_skipped(tmp_path):
    p = write(tmp_path, TOP + rows(5, height="15.65"))
    assert runlog.read(p, check_unit=False).height_m[0] == 15.65


def test_write_is_atomic_on_failure(tmp_path):
    path = tmp_path / "keep.csv"
    path.write_text("old contents\n")
    log = synth.make_log(end=0.05)
    log.height_m = log.height_m[:-1]         # inconsistent: writing must fail
    with pytest.raises(ValueError):
        runlog.write(path, log)
    assert path.read_text() == "old contents\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["keep.csv"]


@pytest.mark.parametrize("column,bad,words", [
    ("compressor", "2", "not 0 or 1"), ("p_spring_pa", "nan", "not a finite number"),
    ("mode", "1.5", "whole number"), ("t_s", "", "empty cell"), ("height_m", "0x1", "not a number"),
    ("p_pipe_pa", '"613633"', None), ("load_n", "4003.4,1", "extra cells")])
def test_a_fault_in_a_format_3_log_names_its_line(tmp_path, column, bad, words):
    """The whole-table reader (one numpy pass) hands any log that is not plain to
    the cell-by-cell reader, which names the row's line; a quoted number is
    still a number (csv rules)."""
    log = synth.make_log(end=2.0)
    path = tmp_path / "r.csv"
    runlog.write(path, log)
    lines = path.read_text().splitlines(keepends=True)
    first = next(i for i, ln in enumerate(lines) if not ln.startswith("#")) + 1
    k = first + 40                       # 0-based index of a data line: file line k + 1
    cells = lines[k].rstrip("\n").split(",")
    cells[runlog.COLUMNS.index(column)] = bad
    lines[k] = ",".join(cells) + "\n"
    path.write_text("".join(lines))
    if words is None:
        assert runlog.read(path).p_pipe_pa[40] == 613633.0
        return
    with pytest.raises(runlog.RunLogError) as e:
        runlog.read(path)
    assert f":{k + 1}:" in str(e.value) and words in str(e.value)


def test_time_that_does_not_increase_names_its_line(tmp_path):
    log = synth.make_log(end=2.0)
    log.t_s[60] = log.t_s[59]
    path = tmp_path / "r.csv"
    runlog.write(path, log)
    first = next(i for i, ln in enumerate(path.read_text().splitlines()) if not ln.startswith("#")) + 1
    with pytest.raises(runlog.RunLogError, match=rf":{first + 61}: column t_s: time .* does not increase"):
        runlog.read(path)

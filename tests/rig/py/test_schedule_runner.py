"""Issue 12: a schedule file's mode / manual rows played on a rig over Modbus TCP.

leveler-schedule-run (libmodbus) plays a manual actuator sequence (the
compressor against the shut spring valve, a spring-valve pulse, a vent
pulse, back to auto) on the unchanged leveler-rig, which drives the plant
served by leveler-plant-server, all real processes over real Modbus TCP. The
rig's own run log must show its actuators following the schedule from each
write on, the writes must land at the schedule's times on the rig's clock,
and the operator must be told about the load change. A schedule error is
named with file, line and field before anything is written."""

import os
import re
import subprocess

import numpy as np

import rigproc as rp
from leveler import runlog

RUNNER = os.environ.get("LEVELER_SCHEDULE_RUN", "")
LB = 4.4482216152605
SCHEDULE = """# manual actuator sequence (issue 12's experiment design)
t_s,load_n,mode,manual_compressor,manual_spring_valve,manual_vent_valve
0,4003.4,,,,
1,4003.4,2,1,0,0
2.5,4003.4,,,1,
3,4003.4,,,0,
4,4003.4,,0,,1
4.3,4003.4,,,,0
5,4003.4,1,0,0,0
6,4893.0,,,,
7,4893.0,,,,
"""
# the requests in force from each row's writes (compressor, spring valve, vent valve); None = auto
EXPECTED = [(1.0, (1, 0, 0)), (2.5, (1, 1, 0)), (3.0, (1, 0, 0)), (4.0, (0, 0, 1)), (4.3, (0, 0, 0)),
            (5.0, None)]
WRITE = re.compile(r"t ([0-9.]+) s \(rig ([0-9.]+) s\): wrote(.*)")


def run_schedule(tmp_path, port, text):
    path = tmp_path / "experiment.csv"
    path.write_text(text)
    return subprocess.run([RUNNER, "--schedule", str(path), "--port", str(port), "--warn-s", "2"],
                          capture_output=True, text=True, timeout=60)


def test_rig_follows_manual_schedule(tmp_path, plant):
    rig = rp.Rig(tmp_path, plant).start()
    try:
        p = run_schedule(tmp_path, rig.port, SCHEDULE)
        print(p.stdout)
        assert p.returncode == 0, p.stderr
    finally:
        rig.stop()
    start = float(re.search(r"start at rig time ([0-9.]+) s", p.stdout).group(1))
    writes = [(float(t), float(rt), what.split()) for t, rt, what in WRITE.findall(p.stdout)]
    assert [w[0] for w in writes] == [1.0, 2.5, 3.0, 4.0, 4.3, 5.0]   # rows with register cells only
    # each row written on the rig's clock within 100 ms of its schedule time: the rig serves
    # supervision between its 10 ms ticks, a row is two requests, and the clock is read after them
    for t, rt, _ in writes:
        assert 0.0 <= rt - start - t < 0.1, (t, rt - start)
    # the manual requests go before the mode in a row: switching to manual takes the new requests at once
    assert " ".join(writes[0][2]) == "manual_compressor = 1 manual_spring_valve = 0 manual_vent_valve = 0 mode = 2"
    assert " ".join(writes[3][2]) == "manual_compressor = 0 manual_vent_valve = 1"
    assert "LOAD soon: set the load to 4893 N (1100 lb) at t 6.0 s" in p.stdout
    assert "LOAD NOW: set the load to 4893 N (1100 lb) at t 6.0 s" in p.stdout
    assert "restored: manual requests 0, mode 1" in p.stdout

    log = runlog.read(tmp_path / "rig.csv")
    acts = np.stack([log.compressor, log.spring_valve, log.vent_valve], axis=1)
    starts = [next(w[1] for w in writes if w[0] == t) for t, _ in EXPECTED]
    checked = 0
    for k, (t, want) in enumerate(EXPECTED[:-1]):
        # from a tick after the row's writes were done to the next row's time (never written earlier)
        lo, hi = starts[k] + 0.03, start + EXPECTED[k + 1][0]
        rows = (log.t_s >= lo) & (log.t_s < hi)
        assert rows.sum() >= 0.25 / 0.01 * 0.8 * min(1.0, (hi - lo) / 0.25), (t, rows.sum())
        got = acts[rows]
        assert (got == np.array(want)).all(), (t, want, got[~(got == np.array(want)).all(axis=1)][:3])
        checked += int(rows.sum())
    # the physics behind it: the compressor against the shut spring valve fills only the pipe
    pipe = log.p_pipe_pa
    before, filled = pipe[np.searchsorted(log.t_s, starts[0])], pipe[np.searchsorted(log.t_s, starts[1]) - 1]
    assert filled > before + 20e3, (before, filled)
    print(f"{checked} logged ticks in manual mode, all as scheduled; pipe {before:.0f} -> {filled:.0f} Pa")


def test_schedule_error_named_before_anything_is_written(tmp_path, plant):
    rig = rp.Rig(tmp_path, plant).start()
    try:
        p = run_schedule(tmp_path, rig.port, "t_s,load_n,mode\n0,4003.4,\n2,4003.4,7\n")
        sv = rig.client()
        mode = sv.read_holding_registers(rp.HR_MODE, count=1).registers[0]
        sv.close()
    finally:
        rig.stop()
    assert p.returncode == 2
    assert "experiment.csv:3: mode: expected an integer 0..2 or empty (got '7')" in p.stderr
    assert mode == 1 and "wrote" not in p.stdout

"""Item 4 of issue 13: a log the disk refuses never tears and never stops
control. leveler-rig runs the thesis 900 lb scenario (lockstep) under a
64 KiB file-size limit (RLIMIT_FSIZE, what `ulimit -f` sets; past it the
kernel sends SIGXFSZ and write() fails with EFBIG, as ENOSPC on a full disk).
The rig must run to the end and exit 0 with the coils safe, flag log_fault
and count log_rows_dropped over supervision, and leave a log the project's
own reader (leveler.runlog) accepts, whose rows plus the dropped ones are
every row the rig wrote, none of the dropped ones. A second test fills a real (tmpfs) disk and frees it again."""

import os
import re
import resource
import subprocess
import time

import numpy as np
import pytest

import rigproc as rp
from leveler import runlog

LIMIT = 64 * 1024


def rig_counts(output):
    """(ticks, rows written, rows dropped) from leveler-rig's last line. Every
    tick logs one row once there is a load reading; a row is written or dropped."""
    m = re.search(r"stopped after (\d+) ticks.* (\d+) log rows written, (\d+) dropped", output)
    assert m, output
    return tuple(int(g) for g in m.groups())


def limit_file_size():
    resource.setrlimit(resource.RLIMIT_FSIZE, (LIMIT, resource.getrlimit(resource.RLIMIT_FSIZE)[1]))


def test_rig_under_a_file_size_limit(tmp_path):
    plant = rp.Plant(tmp_path, config=rp.PLANT_CONFIG, clock="lockstep")
    rig = rp.Rig(tmp_path, plant, clock="lockstep", overrides={"rig": {"run_seconds": 40}})
    try:
        rig.start(preexec_fn=limit_file_size)
        sv = rig.client()

        def flagged():
            fault = sv.read_discrete_inputs(rp.DI_LOG_FAULT, count=1)
            dropped = sv.read_input_registers(rp.IR_LOG_ROWS_DROPPED, count=2)
            return (not fault.isError() and fault.bits[0] and rp.u32(dropped.registers) > 0
                    and rp.u32(dropped.registers))
        seen_dropped = rp.wait_until(flagged, 30.0)
        sv.close()
        assert seen_dropped, "log_fault / log_rows_dropped never showed over supervision"
        assert rig.proc.wait(60) == 0, f"rig ended with {rig.proc.returncode} (-25 = killed by SIGXFSZ)"
        module = plant.client()
        assert not any(module.read_coils(0, count=4).bits[:4]), "outputs not safe after the run"
        module.close()
    finally:
        rig.stop()
        plant.stop()
    ticks, written, dropped = rig_counts(rig.output())
    log = runlog.read(rig.log_path)  # raises on a torn or malformed line
    rows = len(log.t_s)
    size = rig.log_path.stat().st_size
    print(f"{LIMIT} B limit: {ticks} ticks, {rows} rows in the log ({size} B), {dropped} dropped whole "
          f"(first seen over supervision at {seen_dropped}), exit 0, coils safe")
    assert size <= LIMIT
    assert dropped > 0 and rows == written and written + dropped <= ticks
    assert log.t_s[-1] < 40.0 and (log.t_s[1:] > log.t_s[:-1]).all()


def test_rig_on_a_full_tmpfs_then_space_returns(tmp_path, plant):
    """A real full disk (ENOSPC): a 64 KiB tmpfs in a private mount namespace
    (unshare -rm), 48 KiB of it taken by a filler file. The rig (real time)
    fills the rest, drops rows whole, and when the filler is deleted ("space
    returns") writes again, starting with a complete line."""
    disk = tmp_path / "disk"
    disk.mkdir()
    out = tmp_path / "copied.csv"
    probe = subprocess.run(["unshare", "-rm", "sh", "-c", f"mount -t tmpfs -o size=64k none {disk}"],
                           capture_output=True, text=True, timeout=10)
    if probe.returncode != 0:
        pytest.skip(f"no private tmpfs here (unshare -rm: {probe.stderr.strip()}); the file-size limit test covers EFBIG")
    rig = rp.Rig(tmp_path, plant, overrides={"rig": {"run_seconds": 8}, "log": {"path": disk / "rig.csv"}})
    script = (f'mount -t tmpfs -o size=64k none {disk} && head -c 49152 /dev/zero > {disk}/filler && '
              f'{rp.RIG} --config {rig.config_path} 2>{tmp_path}/rig.out; rc=$?; cp {disk}/rig.csv {out}; exit $rc')
    shell = subprocess.Popen(["unshare", "-rm", "sh", "-c", script])
    try:
        rig.port = rp.read_port(rig.port_file, shell)
        sv = rig.client()

        def log_fault():
            return sv.read_discrete_inputs(rp.DI_LOG_FAULT, count=1).bits[0]
        assert rp.wait_until(log_fault, 8.0), "the tmpfs never filled"
        time.sleep(0.5)   # full for half a second: ~50 rows to drop
        assert log_fault()
        dropped_full = rp.u32(sv.read_input_registers(rp.IR_LOG_ROWS_DROPPED, count=2).registers)
        os.unlink(f"/proc/{shell.pid}/root{disk}/filler")   # the shell's mount namespace
        assert rp.wait_until(lambda: not log_fault(), 3.0), "logging did not resume when space returned"
        sv.close()
        assert shell.wait(30) == 0
    finally:
        rp.stop_process(shell)
    ticks, written, dropped = rig_counts((tmp_path / "rig.out").read_text())
    log = runlog.read(out)
    rows = len(log.t_s)
    gaps = np.diff(log.t_s)
    print(f"64 KiB tmpfs, 48 KiB taken: {ticks} ticks, {rows} rows, {dropped} dropped whole while full "
          f"({dropped_full} when space returned), longest gap {gaps.max():.2f} s; reader accepts the log")
    assert dropped > 0 and rows == written and written + dropped <= ticks
    assert dropped >= 40 and gaps.max() > 0.4          # one gap: the rows dropped while full
    assert rows - (np.argmax(gaps) + 1) > 100          # and whole rows again after it

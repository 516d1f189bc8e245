"""Item 4 of issue 13: a log the disk refuses never tears and never stops
control. leveler-rig runs the thesis 900 lb scenario (lockstep) under a
64 KiB file-size limit (RLIMIT_FSIZE, what `ulimit -f` sets; past it the
kernel sends SIGXFSZ and write() fails with EFBIG, as ENOSPC on a full disk).
The rig must run to the end and exit 0 with the coils safe, flag log_fault
and count log_rows_dropped over supervision, and leave a log the project's
own reader (leveler.runlog) accepts, whose rows plus the dropped ones are
every tick."""

import re
import resource

import rigproc as rp
from leveler import runlog

LIMIT = 64 * 1024


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
    m = re.search(r"stopped after (\d+) ticks.* (\d+) log rows dropped", rig.output())
    assert m, rig.output()
    ticks, dropped = int(m.group(1)), int(m.group(2))
    log = runlog.read(rig.log_path)  # raises on a torn or malformed line
    rows = len(log.t_s)
    size = rig.log_path.stat().st_size
    print(f"{LIMIT} B limit: {ticks} ticks, {rows} rows in the log ({size} B), {dropped} dropped whole "
          f"(first seen over supervision at {seen_dropped}), exit 0, coils safe")
    assert size <= LIMIT
    assert dropped > 0 and rows + dropped == ticks
    assert log.t_s[-1] < 40.0 and (log.t_s[1:] > log.t_s[:-1]).all()

"""Issue 23, items 1 and 2: restarts on either side lose nothing.

1. A restarted output module forgets its communication watchdog (the
   register reads 0). The rig must arm it again whenever the module comes
   back, verified here by reading the register of the new module process,
   and a SIGKILL of the rig afterwards must leave the coils safe within the
   watchdog time.
2. A restart of the rig (systemd's Restart=on-failure after a crash) must not
   wipe the log of the run before it: the earlier rows are kept whole."""

import os
import signal
import time

import rigproc as rp
from test_outputs_safe import SLACK_MS, WATCHDOG, WATCHDOG_MS, coils, ms_until_safe, start_charging


def watchdog_register(module):
    r = module.read_holding_registers(rp.MODULE_HR_WATCHDOG_MS, count=1)
    return None if r.isError() else r.registers[0]


def test_watchdog_armed_again_after_each_module_restart(tmp_path):
    plant = rp.Plant(tmp_path)
    rig = rp.Rig(tmp_path, plant, overrides=WATCHDOG).start()
    try:
        for restart in range(3):
            port = plant.port
            plant.stop()  # the module restarts: a new process, its registers at power-on values
            plant = rp.Plant(tmp_path, port=port)
            module = plant.client()
            armed = rp.wait_until(lambda: watchdog_register(module) == WATCHDOG_MS, 3.0)
            print(f"module restart {restart + 1}: watchdog register {watchdog_register(module)} ms")
            assert armed, f"module restart {restart + 1}: watchdog register {watchdog_register(module)}, not {WATCHDOG_MS}"
            module.close()
        module = plant.client()
        sv = rig.client()  # a restart may have latched sensor faults (the link was down): the operator clears them

        def in_control():
            if sv.read_discrete_inputs(rp.DI_FAULT_LATCHED, count=1).bits[0]:
                sv.write_coil(rp.COIL_CLEAR_FAULTS, True)
                return False
            return sv.read_discrete_inputs(rp.DI_SENSORS_VALID, count=1).bits[0]
        assert rp.wait_until(in_control, 5.0, step_s=0.05)
        sv.close()
        start_charging(rig, module)
        os.kill(rig.proc.pid, signal.SIGKILL)
        ms = ms_until_safe(module)
        print(f"SIGKILL after 3 module restarts: coils safe {ms:.0f} ms later")
        assert ms <= WATCHDOG_MS + SLACK_MS
        module.close()
        assert "armed again" in rig.output()
    finally:
        rig.stop()
        plant.stop()


def data_rows(path):
    lines = path.read_text().splitlines()
    header = [line for line in lines if line.startswith("t_s")]
    commas = header[0].count(",") if header else -1   # every row has the header's cells
    assert lines and all(line.count(",") == commas for line in lines if not line.startswith("#")), path
    return [line for line in lines if not line.startswith("#")][1:]


def test_rig_restart_keeps_the_previous_log(tmp_path, plant):
    rig = rp.Rig(tmp_path, plant).start()
    time.sleep(1.0)
    os.kill(rig.proc.pid, signal.SIGKILL)  # a crash: systemd starts it again
    rig.proc.wait()
    rig.out.close()
    first = data_rows(rig.log_path)
    assert len(first) > 50
    rig.start()
    try:
        time.sleep(0.5)
    finally:
        rig.stop()
    kept = data_rows(rig.log_path.with_name(rig.log_path.name + ".1"))
    print(f"run before the restart: {len(first)} rows, kept in {rig.log_path.name}.1: {len(kept)}; "
          f"new run: {len(data_rows(rig.log_path))} rows")
    assert kept == first
    assert len(data_rows(rig.log_path)) > 20

"""Issue 23, item 7: what a module stall and busy Modbus TCP clients cost the operator.

- A stall of the sensor module latches sensor faults; with [faults]
  auto_clear_after_s the rig clears them itself after that long of valid
  sensors, counts each clear in input registers 40-41
  (link_faults_auto_cleared) and says so, at most auto_clear_max_per_hour
  times; past that the faults wait for the operator. (Which faults may be
  auto-cleared at all is tested on auto_clear.c itself: test_auto_clear.c.)
- During an outage stderr gets a few lines, not one per tick.
- Four clients polling every 0.9 s hold all four Modbus TCP client slots; a fifth
  is served anyway: the least recently active gives way."""

import os
import signal
import socket
import struct
import threading
import time

import rigproc as rp

IR_LINK_FAULTS_AUTO_CLEARED = 40
AUTO_CLEAR = {"faults": {"auto_clear_after_s": 1, "auto_clear_max_per_hour": 2}}


def latched(sv):
    return sv.read_discrete_inputs(rp.DI_FAULT_LATCHED, count=1).bits[0]


def auto_cleared(sv):
    return rp.u32(sv.read_input_registers(IR_LINK_FAULTS_AUTO_CLEARED, count=2).registers)


def stall(plant, seconds):
    os.kill(plant.proc.pid, signal.SIGSTOP)
    time.sleep(seconds)
    os.kill(plant.proc.pid, signal.SIGCONT)


def test_link_faults_cleared_by_the_rig_at_most_k_an_hour(tmp_path, plant):
    rig = rp.Rig(tmp_path, plant, overrides=AUTO_CLEAR).start()
    try:
        sv = rig.client()
        assert rp.wait_until(lambda: sv.read_discrete_inputs(rp.DI_SENSORS_VALID, count=1).bits[0], 5.0)
        for n in (1, 2, 3):
            stall(plant, 0.3)
            assert rp.wait_until(lambda: latched(sv), 2.0), f"stall {n}: no fault latched"
            t0 = time.monotonic()
            if n <= 2:
                assert rp.wait_until(lambda: not latched(sv), 5.0), f"stall {n}: not auto-cleared"
                print(f"stall {n}: latched, auto-cleared {time.monotonic() - t0:.1f} s later")
                assert auto_cleared(sv) == n
                state = rp.wait_until(
                    lambda: sv.read_input_registers(rp.IR_CONTROL_STATE, count=1).registers[0] != rp.STATE_SAFE, 3.0)
                assert state, "back in control after the auto-clear"
            else:
                time.sleep(3.0)
                assert latched(sv), "the third in an hour must wait for the operator"
                assert auto_cleared(sv) == 2
                assert not sv.write_coil(rp.COIL_CLEAR_FAULTS, True).isError()
                assert rp.wait_until(lambda: not latched(sv), 2.0)
        sv.close()
    finally:
        rig.stop()
    out = rig.output()
    assert out.count("cleared after 1 s of valid sensors") == 2
    assert "stay latched: 2 auto-clears in the last hour" in out


def test_auto_clear_off_by_default(tmp_path, plant):
    rig = rp.Rig(tmp_path, plant).start()
    try:
        sv = rig.client()
        assert rp.wait_until(lambda: sv.read_discrete_inputs(rp.DI_SENSORS_VALID, count=1).bits[0], 5.0)
        stall(plant, 0.3)
        assert rp.wait_until(lambda: latched(sv), 2.0)
        time.sleep(2.0)
        assert latched(sv) and auto_cleared(sv) == 0
        sv.close()
    finally:
        rig.stop()


def test_outage_costs_a_few_stderr_lines_not_one_per_tick(tmp_path, plant):
    rig = rp.Rig(tmp_path, plant).start()
    try:
        time.sleep(0.5)
        before = len(rig.output().splitlines())
        stall(plant, 3.0)
        time.sleep(0.5)
        lines = rig.output().splitlines()[before:]
    finally:
        rig.stop()
    print(f"3 s module outage: {len(lines)} stderr lines: {lines[:4]}")
    assert len(lines) <= 4, lines


def poll_forever(port, period_s, stop, served):
    c = rp.connect(port)
    while not stop.is_set():
        r = c.read_input_registers(rp.IR_UPTIME_MS, count=2)
        if r.isError():
            c.close()
            try:
                c = rp.connect(port)
            except RuntimeError:
                pass
        else:
            served.append(1)
        stop.wait(period_s)
    c.close()


def test_four_pollers_do_not_lock_out_a_fifth(tmp_path, plant):
    rig = rp.Rig(tmp_path, plant, overrides={"supervision": {"max_clients": 4}}).start()
    stop, served = threading.Event(), []
    pollers = [threading.Thread(target=poll_forever, args=(rig.port, 0.9, stop, served), daemon=True)
               for _ in range(4)]
    try:
        for t in pollers:
            t.start()
        time.sleep(2.0)  # every slot held by a client that polls within the request timeout
        ok = 0
        for attempt in range(5):
            s = socket.create_connection(("127.0.0.1", rig.port), timeout=2.0)
            s.sendall(struct.pack(">HHHBBHH", attempt, 0, 6, 1, 4, rp.IR_UPTIME_MS, 2))
            try:
                reply = s.recv(64)
                ok += len(reply) == 13
            except socket.timeout:
                pass
            s.close()
            time.sleep(0.3)
        print(f"a fifth client beside 4 pollers (every 0.9 s, 4 slots): {ok} of 5 requests answered; "
              f"pollers served {len(served)} times")
        assert ok == 5
    finally:
        stop.set()
        for t in pollers:
            t.join(5)
        rig.stop()
    assert len(served) >= 8, "the pollers keep being served too"

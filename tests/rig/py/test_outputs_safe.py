"""Item 5 of issue 13: outputs safe when leveler-rig dies or hangs.

The rig writes the I/O module's communication watchdog time at start
([outputs] watchdog_ms); leveler-plant-server models the watchdog as real
Modbus I/O modules have it. With the compressor and spring valve on (manual
mode over supervision), SIGKILL and SIGSTOP of the rig must leave the coils
safe within the watchdog time, read from the module by a client whose reads
do not feed the watchdog. The systemd side (sd_notify READY=1, WATCHDOG=1
from the tick loop, silence when the rig hangs) is checked on a notify socket
as systemd itself would listen on."""

import os
import signal
import socket
import time

import pytest

import rigproc as rp

WATCHDOG_MS = 200
SLACK_MS = 60  # the module's own loop and this test's 5 ms polling
WATCHDOG = {"outputs": {"watchdog_ms": WATCHDOG_MS, "watchdog_register": rp.MODULE_HR_WATCHDOG_MS}}


def coils(module):
    r = module.read_coils(0, count=4)
    assert not r.isError()
    return list(r.bits[:4])


def start_charging(rig, module):
    sv = rig.client()
    assert not sv.write_register(rp.HR_MODE, rp.MODE_MANUAL).isError()
    assert not sv.write_coils(rp.COIL_MANUAL_COMPRESSOR, [True, True]).isError()
    assert rp.wait_until(lambda: coils(module)[:2] == [True, True], 3.0), coils(module)
    sv.close()


def ms_until_safe(module, timeout_s=3.0):
    t0 = time.monotonic()
    assert rp.wait_until(lambda: not any(coils(module)), timeout_s, step_s=0.005), "coils still on"
    return (time.monotonic() - t0) * 1000


def test_watchdog_time_written_at_start(tmp_path, plant):
    module = plant.client()
    rig = rp.Rig(tmp_path, plant, overrides=WATCHDOG).start()
    try:
        assert module.read_holding_registers(rp.MODULE_HR_WATCHDOG_MS, count=1).registers[0] == WATCHDOG_MS
    finally:
        rig.stop()
        module.close()


@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGSTOP], ids=["SIGKILL", "SIGSTOP"])
def test_dead_or_stopped_rig_leaves_coils_safe_within_watchdog_time(tmp_path, plant, sig):
    module = plant.client()
    rig = rp.Rig(tmp_path, plant, overrides=WATCHDOG).start()
    try:
        start_charging(rig, module)
        trips = module.read_input_registers(rp.MODULE_IR_WATCHDOG_TRIPS, count=1).registers[0]
        os.kill(rig.proc.pid, sig)
        ms = ms_until_safe(module)
        print(f"{sig.name}: coils safe {ms:.0f} ms later (watchdog {WATCHDOG_MS} ms)")
        assert ms <= WATCHDOG_MS + SLACK_MS
        assert module.read_input_registers(rp.MODULE_IR_WATCHDOG_TRIPS, count=1).registers[0] == trips + 1
        if sig == signal.SIGSTOP:
            os.kill(rig.proc.pid, signal.SIGCONT)
            # Still in manual with both on: the rig's next refresh writes them again.
            assert rp.wait_until(lambda: coils(module)[:2] == [True, True], 3.0)
    finally:
        rig.stop()
        module.close()


def test_no_watchdog_configured_leaves_coils_as_they_were(tmp_path, plant):
    """The control case: without the module watchdog a SIGKILL leaves the coils on (issue 13's field bug)."""
    module = plant.client()
    rig = rp.Rig(tmp_path, plant).start()
    try:
        start_charging(rig, module)
        os.kill(rig.proc.pid, signal.SIGKILL)
        time.sleep((WATCHDOG_MS + SLACK_MS) / 1000)
        assert coils(module)[:2] == [True, True]
    finally:
        rig.stop()
        assert not module.write_coils(0, [False] * 4).isError()
        module.close()


def notify_socket(tmp_path):
    s = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    path = str(tmp_path / "notify.sock")
    s.bind(path)
    s.settimeout(0.05)
    return s, path


def collect(sock, seconds):
    """(time, message) pairs received within seconds."""
    got, until = [], time.monotonic() + seconds
    while time.monotonic() < until:
        try:
            got.append((time.monotonic(), sock.recv(4096).decode()))
        except socket.timeout:
            pass
    return got


def test_systemd_watchdog_notifications(tmp_path, plant):
    module = plant.client()
    assert not module.write_coils(0, [True, True, False, False]).isError()  # left on by a dead process
    sock, path = notify_socket(tmp_path)
    usec = 400_000
    env = dict(os.environ, NOTIFY_SOCKET=path, WATCHDOG_USEC=str(usec))
    rig = rp.Rig(tmp_path, plant, overrides=WATCHDOG).start(env=env)
    try:
        first = collect(sock, 1.0)
        assert first and first[0][1] == "READY=1", first[:3]
        assert not any(coils(module)), "a (re)start drives every output safe"
        beats = [t for t, m in first if m == "WATCHDOG=1"]
        gaps = [b - a for a, b in zip(beats, beats[1:])]
        print(f"WATCHDOG=1 x{len(beats)} in 1 s, largest gap {max(gaps) * 1000:.0f} ms (WATCHDOG_USEC {usec})")
        assert len(beats) >= 3 and max(gaps) < usec / 1e6 / 2
        os.kill(rig.proc.pid, signal.SIGSTOP)
        collect(sock, 0.05)
        silent = collect(sock, usec / 1e6 * 1.5)
        assert not silent, "a hung rig must go silent so systemd kills and restarts it"
        os.kill(rig.proc.pid, signal.SIGCONT)
        assert any(m == "WATCHDOG=1" for _, m in collect(sock, 0.5))
        rig.proc.terminate()
        assert rig.proc.wait(10) == 0
        assert any(m == "STOPPING=1" for _, m in collect(sock, 0.2))
    finally:
        rig.stop()
        sock.close()
        module.close()

"""Items 2, 3, 6 (addresses), 8 and 9 (writers) of issue 13 on leveler-rig's
Modbus TCP server, with pymodbus, raw sockets and mbpoll (Debian) as
independent clients, all on loopback."""

import socket
import struct
import subprocess
import threading
import time
from pathlib import Path

import pytest

import rigproc as rp


def request(tid, function, body=b"", unit=1):
    pdu = bytes([function]) + body
    return struct.pack(">HHHB", tid, 0, len(pdu) + 1, unit) + pdu


def read_reply(sock, timeout_s=2.0):
    """One MBAP frame, or None on timeout/close."""
    sock.settimeout(timeout_s)
    buf = b""
    try:
        while len(buf) < 7 or len(buf) < 6 + struct.unpack(">H", buf[4:6])[0]:
            chunk = sock.recv(512)
            if not chunk:
                return None
            buf += chunk
    except socket.timeout:
        return None
    n = 6 + struct.unpack(">H", buf[4:6])[0]
    assert len(buf) == n, "one reply at a time expected here"
    return buf


def closed_by_peer(sock, timeout_s):
    sock.settimeout(timeout_s)
    try:
        while sock.recv(64):
            pass
        return True
    except (socket.timeout, BlockingIOError):
        return False
    except OSError:
        return True


@pytest.fixture
def rig(tmp_path, plant):
    r = rp.Rig(tmp_path, plant, overrides={"supervision": {"max_clients": 4, "request_timeout_ms": 500}}).start()
    yield r
    r.stop()


class Attack:
    """slow clients (one byte every 100 ms, never a whole request) and idle
    connections, each reopened as soon as the rig drops it."""

    def __init__(self, port, slow=8, idle=16):
        self.port, self.stop_flag = port, threading.Event()
        self.slow = [self._open() for _ in range(slow)]
        self.idle = [self._open() for _ in range(idle)]
        self.reopened = 0
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _open(self):
        s = socket.create_connection(("127.0.0.1", self.port))
        s.setblocking(False)
        return s

    def _run(self):
        frame = request(7, 4, struct.pack(">HH", 0, 1))
        sent = 0
        while not self.stop_flag.is_set():
            for group, payload in ((self.slow, frame[sent % (len(frame) - 1):][:1]), (self.idle, b"")):
                for i, s in enumerate(group):
                    try:
                        if payload:
                            s.send(payload)
                        elif s.recv(1) == b"":
                            raise ConnectionResetError
                    except BlockingIOError:
                        pass
                    except OSError:
                        s.close()
                        group[i] = self._open()
                        self.reopened += 1
            sent += 1
            time.sleep(0.1)

    def close(self):
        self.stop_flag.set()
        self.thread.join(5)
        for s in self.slow + self.idle:
            s.close()


def test_slow_and_idle_clients_cannot_lock_out_a_client_with_requests(rig):
    attack = Attack(rig.port)
    try:
        time.sleep(1.0)  # the attack holds every slot it can
        served = 0
        for _ in range(15):
            try:
                c = rp.connect(rig.port)
                r = c.read_input_registers(rp.IR_UPTIME_MS, count=2)
                served += not r.isError()
                c.close()
            except Exception:  # connection refused or reset: not served
                pass
            time.sleep(0.1)
        print(f"under 8 slow + 16 idle connections (max_clients 4): {served} of 15 clients served, "
              f"{attack.reopened} attacker connections dropped and reopened")
        assert served == 15
        assert attack.reopened > 0
    finally:
        attack.close()


def test_a_slow_client_is_dropped_at_the_request_deadline(rig):
    s = socket.create_connection(("127.0.0.1", rig.port))
    frame = request(1, 4, struct.pack(">HH", 0, 1))
    t0 = time.monotonic()
    dropped = False
    for b in frame[:-1]:  # one byte every 100 ms: each would have reset the old idle timer
        try:
            s.send(bytes([b]))
        except OSError:
            dropped = True
            break
        time.sleep(0.1)
    dropped = dropped or closed_by_peer(s, 2.0)
    elapsed = time.monotonic() - t0
    print(f"slow client dropped {elapsed * 1000:.0f} ms after its first byte (request_timeout_ms 500)")
    assert dropped and elapsed < 1.5
    s.close()


def test_every_pipelined_request_in_a_segment_is_answered(rig):
    s = socket.create_connection(("127.0.0.1", rig.port))
    segment = b"".join(request(tid, 4, struct.pack(">HH", rp.IR_UPTIME_MS, 2)) for tid in range(1, 21))
    s.sendall(segment)
    s.settimeout(2.0)
    buf, until = b"", time.monotonic() + 2.0
    while time.monotonic() < until and len(buf) < 20 * 13:
        try:
            buf += s.recv(4096)
        except socket.timeout:
            break
    tids = [struct.unpack(">H", buf[i:i + 2])[0] for i in range(0, len(buf), 13)]
    print(f"20 requests in one segment: {len(tids)} replies")
    assert tids == list(range(1, 21))
    s.close()


@pytest.mark.parametrize("function", [0x83, 0xFF, 0x41, 0x2B])
def test_exception_function_code_never_wraps(rig, function):
    s = socket.create_connection(("127.0.0.1", rig.port))
    s.sendall(request(5, function, struct.pack(">HH", 0, 1)))
    reply = read_reply(s)
    assert reply is not None
    assert reply[:2] == b"\x00\x05" and reply[7] == (function | 0x80) and reply[8] == 0x01
    s.close()


def test_writers_allowlist(tmp_path, plant):
    rig = rp.Rig(tmp_path, plant, overrides={"supervision": {"writers": "127.0.0.2, ::1"}}).start()
    try:
        denied = rp.connect(rig.port)  # from 127.0.0.1
        r = denied.write_register(rp.HR_MODE, rp.MODE_MANUAL)
        assert r.isError() and r.exception_code == 1
        assert not denied.read_input_registers(rp.IR_UPTIME_MS, count=2).isError()  # reading is fine
        denied.close()
        writer = rp.connect(rig.port, source_address=("127.0.0.2", 0))
        assert not writer.write_register(rp.HR_MODE, rp.MODE_MANUAL).isError()
        assert writer.read_holding_registers(rp.HR_MODE, count=1).registers[0] == rp.MODE_MANUAL
        writer.close()
    finally:
        rig.stop()


def mbpoll(port, *args, host="127.0.0.1"):
    cmd = ["mbpoll", "-m", "tcp", "-a", "1", "-0", "-1", "-o", "2", "-p", str(port), *args, host]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=10)


def mbpoll_values(out):
    return {int(k.strip("[]")): int(v) for k, v in (line.split(":")[:2] for line in out.splitlines()
                                                  if line.startswith("["))}


@pytest.mark.parametrize("address,host", [("::1", "::1"), ("localhost", "127.0.0.1")])
def test_mbpoll_reads_and_writes(tmp_path, plant, address, host):
    """mbpoll as an independent client; the rig bound to ::1 (IPv6) or localhost (= 127.0.0.1)."""
    rig = rp.Rig(tmp_path, plant, overrides={"supervision": {"address": address}}).start()
    try:
        up = [mbpoll(rig.port, "-t", "3", "-r", str(rp.IR_UPTIME_MS), "-c", "2", host=host) for _ in range(2)]
        assert all(u.returncode == 0 for u in up), up[0].stdout + up[0].stderr
        ms = [(v[rp.IR_UPTIME_MS] << 16) | v[rp.IR_UPTIME_MS + 1] for v in map(mbpoll_values, (u.stdout for u in up))]
        assert ms[1] > ms[0] > 0
        w = subprocess.run(["mbpoll", "-m", "tcp", "-a", "1", "-0", "-1", "-p", str(rig.port), "-t", "4", "-r",
                            str(rp.HR_MODE), host, str(rp.MODE_MANUAL)], capture_output=True, text=True, timeout=10)
        assert w.returncode == 0, w.stdout + w.stderr
        c = rp.connect(rig.port, host=host)
        assert c.read_holding_registers(rp.HR_MODE, count=1).registers[0] == rp.MODE_MANUAL
        c.close()
        print(f"mbpoll on {host}: uptime {ms[0]} -> {ms[1]} ms, mode written 2 and read back by pymodbus")
    finally:
        rig.stop()


def readme_mbpoll_command():
    """The mbpoll line a user copies from boards/linux-rig/README.md."""
    readme = Path(__file__).resolve().parents[3] / "boards" / "linux-rig" / "README.md"
    line = next(l for l in readme.read_text().splitlines() if l.startswith("mbpoll -m tcp"))
    return line.split("#")[0].split()


def test_the_readmes_mbpoll_command_reads_the_right_values(tmp_path, plant):
    """The README's mbpoll example, run as written (its port replaced, one poll),
    reads the same height and P2 as pymodbus does; without its word-order flag
    the same registers read as garbage."""
    rig = rp.Rig(tmp_path, plant).start()
    try:
        cmd = readme_mbpoll_command()
        cmd[cmd.index("-p") + 1] = str(rig.port)
        cmd += ["-1", "-o", "2"]
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=10)
        assert p.returncode == 0, p.stdout + p.stderr
        got = mbpoll_values(p.stdout)
        c = rp.connect(rig.port)
        regs = c.read_input_registers(0, count=4).registers
        c.close()
        height_um, p_spring_pa = [struct.unpack(">i", struct.pack(">HH", regs[i], regs[i + 1]))[0] for i in (0, 2)]
        assert set(got) == {1, 3, 5, 7}, p.stdout          # four 32-bit values, 1-based references
        assert abs(got[1] - height_um) < 2000 and 0.30e6 < got[1] < 0.50e6, (got, height_um)   # um, platform moves slowly
        assert abs(got[3] - p_spring_pa) < 20000 and 3e5 < got[3] < 1e6, (got, p_spring_pa)
        no_b = [a for a in cmd if a != "-B"]
        garbled = mbpoll_values(subprocess.run(no_b, capture_output=True, text=True, timeout=10).stdout)
        assert not 0.30e6 < garbled[1] < 0.50e6, garbled     # the flag is what makes it right
        print(f"README mbpoll: height {got[1]} um, P2 {got[3]} Pa; without -B height reads {garbled[1]}")
    finally:
        rig.stop()

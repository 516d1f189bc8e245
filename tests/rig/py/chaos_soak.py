"""The chaos soak (issue 23): leveler-rig (real time, 10 ms ticks) against
leveler-plant-server under a random load schedule while an injector fires
overlapping faults every 5-20 s, a Modbus TCP client polling at 10 Hz.

    chaos_soak.py --seconds 600 --seed 23 --work DIR

Faults (kind, duration and time from the seed alone, so the schedule is the
same on every run): module stalls (SIGSTOP 50-1000 ms) and restarts (SIGKILL,
a new module process on the same port 0.1-0.5 s later), refused writes
(out-of-range values through the write socket, any write over plain TCP),
slow clients (a byte every 100 ms) and idle ones, a full-disk window (the
log's tmpfs filled for 0.5-3 s; needs `unshare -rm`), and a TLS client
without a certificate (leveler-mbaps must refuse it).

Counted, each must be zero:
  unsafe_states          a coil on at the module while the rig holds its
                         outputs safe for more than 0.3 s (the module
                         watchdog's 200 ms and slack; not while the module
                         itself is frozen or restarting), or the compressor
                         on above the overpressure limit
  missed_ticks           tick_overruns increments with no fault under way
                         (those while the machine was short of CPU are
                         printed apart: a probe process beside the rig woke
                         late, the rig or its module waited on a run queue
                         for half a tick, or the hypervisor stole a tick's
                         worth, 10 ms; the share of polls so marked is
                         printed)
  rig_exits              the rig ended before the soak did
  torn_log_rows          lines with other than 10 fields in the run logs
  lost_log_rows          rows dropped outside a full-disk window, and gaps of
                         more than 50 ms between rows with no fault under way
                         (a gap is the log's view of skipped ticks: one the
                         rig's own overrun count, taken in CPU-starved polls
                         within 0.2 s of it, accounts for tick by tick is
                         printed apart with those ticks)
  refused_writes_changed a refused write after which a holding register differs
  tls_without_cert_let_in a TLS client without a certificate got a reply
  failed_polls           10 Hz polls that failed with no fault under way
  watchdog_not_rearmed   module restarts after which the watchdog register
                         did not read watchdog_ms within 3 s
The watchdog register read after every module restart is printed."""

from __future__ import annotations

import argparse
import json
import logging
import os
import random
import shutil
import signal
import socket
import ssl
import struct
import subprocess
import sys
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
import rigproc as rp  # noqa: E402

ROOT = Path(__file__).resolve().parents[3]
REGS = {r["name"]: r for r in json.loads((ROOT / "firmware/regmap/registers.json").read_text())["registers"]}
HR_SIZE = max(r["address"] + (2 if r["type"] in ("int32", "uint32") else 1)
              for r in REGS.values() if r["table"] == "holding")
WATCHDOG_MS = 200
UNSAFE_AFTER_S = 0.3  # outputs on while held safe for longer than the module watchdog (+ slack)
SETTLE_S = {"stall": 3.0, "restart": 3.0, "full_disk": 1.0}  # after the fault: link faults auto-clear in 1 s
KINDS = ("stall", "restart", "bad_writes", "slow_clients", "idle_clients", "full_disk", "tls_nocert")
MBAPS = os.environ.get("LEVELER_MBAPS", "")
# A process beside the rig that sleeps 5 ms at a time and prints when it woke
# more than 8 ms late: the machine, not the rig, was short of CPU then.
PROBE = ("import time,sys\n"
         "while True:\n"
         "    t = time.monotonic(); time.sleep(0.005); late = time.monotonic() - t - 0.005\n"
         "    if late > 0.008: print(f'{t:.4f} {late:.4f}', flush=True)\n")
TICK_S = 0.01            # the rig's tick
RUN_WAIT_NS = 5_000_000  # the rig or its module runnable but not run for half a tick
STEAL_JIFFIES = 1        # a tick's worth (10 ms) of CPU taken by the hypervisor between two polls


def run_wait_ns(pids):
    """Nanoseconds the processes' threads have waited on a run queue
    (field 2 of /proc/PID/task/TID/schedstat): ready to run, not running."""
    total = 0
    for pid in pids:
        for f in Path(f"/proc/{pid}/task").glob("*/schedstat"):
            try:
                total += int(f.read_text().split()[1])
            except (OSError, IndexError, ValueError):
                pass  # a thread or process gone meanwhile
    return total


def steal_jiffies():
    """CPU time the hypervisor took from this machine (/proc/stat, steal)."""
    with open("/proc/stat") as f:
        return int(f.readline().split()[8])


def addr(name):
    return REGS[name]["address"]


class Windows:
    """Time intervals during which a fault is under way (plus its settling)."""

    def __init__(self):
        self.lock, self.spans = threading.Lock(), []

    def add(self, kind, t0, t1):
        with self.lock:
            self.spans.append((kind, t0, t1))

    def active(self, t, kinds=None):
        with self.lock:
            return any(a - 0.1 <= t <= b and (kinds is None or k in kinds) for k, a, b in self.spans)

    def open(self, kind, t0):
        """A span still under way (ends at infinity until closed)."""
        with self.lock:
            self.spans.append((kind, t0, float("inf")))
            return len(self.spans) - 1

    def close(self, i, t1):
        with self.lock:
            k, a, _ = self.spans[i]
            self.spans[i] = (k, a, t1)


def schedule_csv(path, seconds, rng):
    """A random load schedule: 3500-5000 N, a new load every 3-15 s."""
    t, rows = 0.0, []
    while t <= seconds + 60:
        rows.append(f"{t:.2f},{rng.uniform(3500, 5000):.1f}")
        t += rng.uniform(3, 15)
    rows.append(f"{t:.2f},4000.0")
    path.write_text("t_s,load_n\n" + "\n".join(rows) + "\n")


def fault_plan(seconds, rng):
    """(time, kind, duration) from the seed alone: every 5-20 s, overlapping;
    kinds dealt from a shuffled deck, so a short run still sees most of them."""
    plan, t, deck = [], rng.uniform(5, 20), []
    while t < seconds - 8:
        if not deck:
            deck = list(KINDS)
            rng.shuffle(deck)
        kind = deck.pop()
        dur = {"stall": rng.uniform(0.05, 1.0), "restart": rng.uniform(0.1, 0.5), "full_disk": rng.uniform(0.5, 3.0),
               "slow_clients": rng.uniform(2, 8), "idle_clients": rng.uniform(2, 8)}.get(kind, 0.0)
        plan.append((round(t, 3), kind, round(dur, 3)))
        t += rng.uniform(5, 20)
    return plan


def make_pki(d):
    d.mkdir(parents=True, exist_ok=True)

    def openssl(*args):
        subprocess.run(["openssl", *args], cwd=d, check=True, capture_output=True, timeout=30)
    openssl("req", "-x509", "-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes", "-keyout",
            "ca.key", "-out", "ca.pem", "-days", "2", "-subj", "/CN=soak-ca")
    (d / "server.ext").write_text("subjectAltName=IP:127.0.0.1\nextendedKeyUsage=serverAuth\n")
    openssl("req", "-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes", "-keyout", "server.key",
            "-out", "server.csr", "-subj", "/CN=server")
    openssl("x509", "-req", "-in", "server.csr", "-CA", "ca.pem", "-CAkey", "ca.key", "-CAcreateserial", "-out",
            "server.pem", "-days", "2", "-extfile", "server.ext")


class Soak:
    def __init__(self, args):
        self.args, self.work = args, Path(args.work)
        shutil.rmtree(self.work, ignore_errors=True)
        self.work.mkdir(parents=True)
        self.rng = random.Random(args.seed)
        self.windows = Windows()
        self.counts = {k: 0 for k in ("unsafe_states", "missed_ticks", "rig_exits", "torn_log_rows", "lost_log_rows",
                                      "refused_writes_changed", "tls_without_cert_let_in", "failed_polls",
                                      "watchdog_not_rearmed")}
        self.watchdog_after_restart, self.faults_fired, self.notes = [], {k: 0 for k in KINDS}, []
        self.plant_lock, self.stop = threading.Lock(), threading.Event()
        self.probe_lock, self.probe_late, self.starved_ticks = threading.Lock(), [], 0
        self.starved_spans, self.starved_gaps = [], []  # (soak t0, t1, ticks skipped); gaps they account for
        self.short = {"run_queue": 0, "steal": 0, "polls": 0}  # polls with the rig or its module starved, by cause
        self.t0 = time.monotonic()

    def now(self):
        return time.monotonic() - self.t0

    # ---- processes ----
    def start_plant(self, port=0):
        port_file = self.work / "plant.port"
        port_file.unlink(missing_ok=True)
        out = open(self.work / "plant.out", "a")
        self.plant = subprocess.Popen([rp.PLANT_SERVER, "--config", rp.PLANT_CONFIG, "--port", str(port),
                                       "--port-file", str(port_file), "--clock", "realtime", "--max-seconds",
                                       str(self.args.seconds + 120), "--schedule", str(self.work / "load.csv")],
                                      stdout=out, stderr=subprocess.STDOUT)
        out.close()
        self.plant_port = rp.read_port(port_file, self.plant, output=self.work / "plant.out")

    def start_rig(self):
        self.disk = self.work / "disk"
        self.disk.mkdir()
        probe = subprocess.run(["unshare", "-rm", "sh", "-c", f"mount -t tmpfs -o size=32m none {self.disk}"],
                               capture_output=True, text=True, timeout=10)
        self.private_disk = probe.returncode == 0
        if not self.private_disk:
            self.notes.append(f"full-disk windows not injected (no private tmpfs: {probe.stderr.strip()})")
        self.rig = rp.Rig(self.work, type("P", (), {"port": self.plant_port})(), overrides={
            "sensors": {"timeout_ms": 5},
            "outputs": {"watchdog_ms": WATCHDOG_MS, "watchdog_register": rp.MODULE_HR_WATCHDOG_MS},
            "supervision": {"write_socket": self.work / "sv.sock", "max_clients": 4, "request_timeout_ms": 500},
            "log": {"path": self.disk / "rig.csv", "rotate_bytes": 1000000, "keep_files": 100},
            "faults": {"auto_clear_after_s": 1, "auto_clear_max_per_hour": 60},
            "mbaps": {"address": "127.0.0.1", "port": 0, "port_file": self.work / "mbaps.port",
                      "cert": self.work / "pki/server.pem", "key": self.work / "pki/server.key",
                      "ca": self.work / "pki/ca.pem"}})
        rig_out = self.work / "rig.out"
        if self.private_disk:
            script = (f"mount -t tmpfs -o size=32m none {self.disk} && {{ {rp.RIG} --config {self.rig.config_path} "
                      f"2>{rig_out}; rc=$?; mkdir -p {self.work}/logs; cp {self.disk}/rig.csv* {self.work}/logs/; "
                      f"exit $rc; }}")
            self.rig.proc = subprocess.Popen(["unshare", "-rm", "sh", "-c", script])
        else:
            self.rig.proc = subprocess.Popen([rp.RIG, "--config", str(self.rig.config_path)],
                                             stderr=open(rig_out, "w"))
        self.rig.port = rp.read_port(self.rig.port_file, self.rig.proc, timeout_s=30, output=rig_out)
        self.mbaps = subprocess.Popen([MBAPS, "--config", str(self.rig.config_path)],
                                      stderr=open(self.work / "mbaps.out", "w"))
        self.mbaps_port = rp.read_port(self.work / "mbaps.port", self.mbaps, output=self.work / "mbaps.out")

    # ---- the Modbus TCP client polling at 10 Hz ----
    def poll_rig(self):
        sv, module = rp.connect(self.rig.port), None
        prev_overruns, prev_dropped, prev_t, on_since = None, None, None, None
        prev_cpu, next_t = None, time.monotonic()
        while not self.stop.is_set():
            next_t = max(next_t + 0.1, time.monotonic())  # a late poll is not made up by a burst
            self.stop.wait(max(0.0, next_t - time.monotonic()))
            t = self.now()
            try:
                ir = sv.read_input_registers(0, count=42)
                di = sv.read_discrete_inputs(0, count=10)
                hr = sv.read_holding_registers(addr("overpressure_limit_pa"), count=2)
                if ir.isError() or di.isError() or hr.isError():
                    raise RuntimeError(str(ir))
            except Exception:
                if not self.windows.active(t):
                    self.counts["failed_polls"] += 1
                    self.notes.append(f"t={t:.1f} s: poll failed with no fault under way")
                try:
                    sv.close()
                    sv = rp.connect(self.rig.port)
                except Exception:
                    pass
                continue
            r = ir.registers
            overruns, dropped = rp.u32(r[24:26]), rp.u32(r[34:36])
            cpu, cpu_short = self.cpu_sample(), None
            if prev_cpu is not None:
                cpu_short = self.cpu_short(prev_cpu, cpu)
                waited = (f"the rig and its module waited {(cpu[0] - prev_cpu[0]) / 1e6:.1f} ms on a run queue, "
                          f"{(cpu[1] - prev_cpu[1]) * 10} ms stolen")
            prev_cpu = cpu
            quiet = not self.windows.active(t) and prev_t is not None and not self.windows.active(prev_t)
            if prev_overruns is not None and overruns > prev_overruns and quiet:
                if cpu_short or self.starved(prev_t - 0.05, t):
                    self.starved_ticks += overruns - prev_overruns
                    self.starved_spans.append((prev_t, t, overruns - prev_overruns))
                else:
                    self.counts["missed_ticks"] += overruns - prev_overruns
                    self.notes.append(f"t={t:.1f} s: {overruns - prev_overruns} missed ticks with no fault under way "
                                      f"({waited})")
            if prev_dropped is not None and dropped > prev_dropped and not self.windows.active(t, ("full_disk",)):
                self.counts["lost_log_rows"] += dropped - prev_dropped
                self.notes.append(f"t={t:.1f} s: {dropped - prev_dropped} log rows dropped outside a full disk")
            prev_overruns, prev_dropped, prev_t = overruns, dropped, t
            # the physical outputs, read from the module (reads do not feed its watchdog)
            try:
                if module is None:
                    module = rp.connect(self.plant_port)
                coils = module.read_coils(0, count=4)
                coils = None if coils.isError() else coils.bits[:4]
            except Exception:
                coils, module = None, None
            if coils is None or self.windows.active(t, ("restart", "stall_frozen")):
                on_since = None  # a frozen or restarting module: nobody can drive its outputs
                continue
            held_safe = di.bits[addr("outputs_safe")]
            on_since = (on_since or t) if held_safe and any(coils) else None
            limit = rp.u32(hr.registers)
            p_max = max(rp.u32(r[addr("p_spring_pa"):addr("p_spring_pa") + 2]),
                        rp.u32(r[addr("p_pipe_pa"):addr("p_pipe_pa") + 2]))
            over = coils[0] and p_max > limit
            if (on_since is not None and t - on_since > UNSAFE_AFTER_S) or over:
                on_since = None
                self.counts["unsafe_states"] += 1
                self.notes.append(f"t={t:.1f} s: unsafe: coils {coils}, outputs held safe {held_safe}, "
                                  f"p {p_max} Pa (limit {limit})")
        sv.close()
        if module:
            module.close()

    def cpu_sample(self):
        """(run-queue wait of the rig and its module in ns, steal in jiffies)."""
        with self.plant_lock:
            pids = self.rig_pids() + [self.plant.pid]
        return run_wait_ns(pids), steal_jiffies()

    def cpu_short(self, before, after):
        """Why the machine was short of CPU for the rig between two samples, or None."""
        self.short["polls"] += 1
        cause = ("run_queue" if after[0] - before[0] >= RUN_WAIT_NS else
                 "steal" if after[1] - before[1] >= STEAL_JIFFIES else None)
        if cause:
            self.short[cause] += 1
        return cause

    def rig_pids(self):
        """The rig's process: under unshare, the shell's only child."""
        kids = Path(f"/proc/{self.rig.proc.pid}/task/{self.rig.proc.pid}/children")
        try:
            return [int(p) for p in kids.read_text().split()] if self.private_disk else [self.rig.proc.pid]
        except OSError:
            return [self.rig.proc.pid]

    def starved(self, a, b):
        """The probe process woke late between soak times a and b."""
        with self.probe_lock:
            return any(a <= t - self.t0 <= b for t in self.probe_late)

    def read_probe(self):
        for line in self.probe.stdout:
            t, late = map(float, line.split())
            with self.probe_lock:
                self.probe_late.append(t)

    # ---- faults ----
    def fault(self, kind, dur):
        t0 = self.now()
        span = self.windows.open(kind, t0)
        try:
            getattr(self, "f_" + kind)(dur)
        finally:
            self.windows.close(span, self.now() + SETTLE_S.get(kind, 0.5))
        self.faults_fired[kind] += 1

    def f_stall(self, dur):
        with self.plant_lock:
            t0 = self.now()
            os.kill(self.plant.pid, signal.SIGSTOP)
            time.sleep(dur)
            os.kill(self.plant.pid, signal.SIGCONT)
            self.windows.add("stall_frozen", t0, self.now() + 0.05)

    def f_restart(self, dur):
        with self.plant_lock:
            self.plant.kill()
            self.plant.wait()
            time.sleep(dur)
            self.start_plant(self.plant_port)
        c = rp.connect(self.plant_port)
        armed = rp.wait_until(lambda: c.read_holding_registers(rp.MODULE_HR_WATCHDOG_MS, count=1).registers[0]
                              == WATCHDOG_MS, 3.0, 0.02)
        value = c.read_holding_registers(rp.MODULE_HR_WATCHDOG_MS, count=1).registers[0]
        c.close()
        self.watchdog_after_restart.append(value)
        if not armed:
            self.counts["watchdog_not_rearmed"] += 1

    def holding(self):
        c = rp.connect(self.rig.port)
        try:
            return list(c.read_holding_registers(0, count=HR_SIZE).registers)
        finally:
            c.close()

    def f_bad_writes(self, dur):
        mode, lower = addr("mode"), addr("band_lower_um")
        bad = [(6, struct.pack(">HH", mode, 7)),                              # mode out of range
               (16, struct.pack(">HHBI", lower, 2, 4, 999999)),               # band lower above upper
               (16, struct.pack(">HHBH", lower, 1, 2, 1)),                    # half of a 32-bit value
               (6, struct.pack(">HH", addr("overpressure_limit_pa") + 1, 0))]
        for fc, body in bad:
            for where in ("socket", "tcp"):
                before = self.holding()
                if where == "socket":
                    s = socket.socket(socket.AF_UNIX)
                    s.connect(str(self.work / "sv.sock"))
                else:
                    s = socket.create_connection(("127.0.0.1", self.rig.port), timeout=2)
                s.settimeout(2)
                pdu = bytes([fc]) + body
                s.sendall(struct.pack(">HHHB", 1, 0, len(pdu) + 1, 1) + pdu)
                try:
                    reply = s.recv(64)
                except OSError:
                    reply = b""
                s.close()
                refused = len(reply) >= 9 and reply[7] & 0x80
                if not refused:
                    self.notes.append(f"a bad write ({where}, FC {fc}) was not refused: {reply.hex()}")
                if self.holding() != before:
                    self.counts["refused_writes_changed"] += 1
                    self.notes.append(f"a refused write ({where}, FC {fc}) changed the holding registers")
        # and a valid write over plain TCP: refused (write_socket), nothing changed
        before = self.holding()
        c = rp.connect(self.rig.port)
        r = c.write_register(mode, 0)
        c.close()
        if not r.isError() or self.holding() != before:
            self.counts["refused_writes_changed"] += 1
            self.notes.append("a write over plain TCP was taken")

    def f_slow_clients(self, dur):
        socks = [socket.create_connection(("127.0.0.1", self.rig.port), timeout=2) for _ in range(3)]
        frame = struct.pack(">HHHBBHH", 9, 0, 6, 1, 4, 0, 1)
        end, i = time.monotonic() + dur, 0
        while time.monotonic() < end:
            for s in socks:
                try:
                    s.send(frame[i % (len(frame) - 1):][:1])
                except OSError:
                    pass
            i += 1
            time.sleep(0.1)
        for s in socks:
            s.close()

    def f_idle_clients(self, dur):
        socks = [socket.create_connection(("127.0.0.1", self.rig.port), timeout=2) for _ in range(6)]
        time.sleep(dur)
        for s in socks:
            s.close()

    def f_full_disk(self, dur):
        if not self.private_disk:
            return
        filler = Path(f"/proc/{self.rig.proc.pid}/root{self.disk}/filler")
        try:
            with open(filler, "wb") as f:
                chunk = b"\0" * (1 << 20)
                while True:
                    f.write(chunk)
                    f.flush()
        except OSError:
            pass
        time.sleep(dur)
        filler.unlink(missing_ok=True)

    def f_tls_nocert(self, dur):
        ctx = ssl.create_default_context(ssl.Purpose.SERVER_AUTH, cafile=str(self.work / "pki/ca.pem"))
        ctx.check_hostname = False
        try:
            with ctx.wrap_socket(socket.create_connection(("127.0.0.1", self.mbaps_port), timeout=3)) as s:
                s.sendall(struct.pack(">HHHBBHH", 1, 0, 6, 1, 6, addr("mode"), 0))
                if s.recv(64):
                    self.counts["tls_without_cert_let_in"] += 1
        except (ssl.SSLError, OSError):
            pass

    # ---- the run ----
    def run(self):
        schedule_csv(self.work / "load.csv", self.args.seconds, self.rng)
        plan = fault_plan(self.args.seconds, self.rng)
        make_pki(self.work / "pki")
        self.t0 = time.monotonic()
        self.start_plant()
        self.start_rig()
        c = rp.connect(self.rig.port)
        self.rig_offset = self.now() - rp.u32(c.read_input_registers(rp.IR_UPTIME_MS, count=2).registers) / 1000
        c.close()
        print(f"chaos soak: {self.args.seconds} s, seed {self.args.seed}, {len(plan)} faults "
              f"({', '.join(f'{k} {sum(1 for _, kk, _ in plan if kk == k)}' for k in KINDS)})", flush=True)
        self.probe = subprocess.Popen([sys.executable, "-c", PROBE], stdout=subprocess.PIPE, text=True)
        threading.Thread(target=self.read_probe, daemon=True).start()
        time.sleep(2.0)
        poller = threading.Thread(target=self.poll_rig, daemon=True)
        poller.start()
        threads = []
        for t, kind, dur in plan:
            while self.now() < t and self.rig.proc.poll() is None:
                time.sleep(0.02)
            th = threading.Thread(target=self.fault, args=(kind, dur), daemon=True)
            th.start()
            threads.append(th)
            if self.args.progress and len(threads) % 10 == 0:
                print(f"  t={self.now():.0f} s: {len(threads)} faults fired", flush=True)
        while self.now() < self.args.seconds and self.rig.proc.poll() is None:
            time.sleep(0.1)
        for th in threads:
            th.join(15)
        self.stop.set()
        poller.join(10)
        if self.rig.proc.poll() is not None:
            self.counts["rig_exits"] += 1
            self.notes.append(f"the rig exited with {self.rig.proc.returncode} during the soak")
        self.shutdown()
        self.check_logs()
        return self.report()

    def shutdown(self):
        rp.stop_process(self.probe)
        rp.stop_process(self.mbaps)
        if self.rig.proc.poll() is None:
            for pid in self.rig_pids():  # the rig itself, not unshare's shell
                os.kill(pid, signal.SIGTERM)
            try:
                self.rig.proc.wait(20)
            except subprocess.TimeoutExpired:
                self.rig.proc.kill()
                self.rig.proc.wait()
        with self.plant_lock:
            rp.stop_process(self.plant)

    def check_logs(self):
        logs = self.work / "logs" if self.private_disk else self.disk
        files = sorted(logs.glob("rig.csv*"), key=lambda p: -int(p.suffix[1:]) if p.suffix[1:].isdigit() else 0)
        times = []
        for f in files:
            text = f.read_text()
            if text and not text.endswith("\n"):
                self.counts["torn_log_rows"] += 1
            header_commas = None
            for line in text.splitlines():
                if line.startswith("t_s"):
                    header_commas = line.count(",")   # every row has the header's cells
                if line.startswith("#") or line.startswith("t_s"):
                    continue
                if line.count(",") != header_commas:
                    self.counts["torn_log_rows"] += 1
                    continue
                times.append(float(line.split(",", 1)[0]))
        self.log_rows = len(times)
        offset = self.rig_offset  # rig time (its uptime) -> soak time
        for a, b in zip(times, times[1:]):
            if b <= a:
                self.counts["torn_log_rows"] += 1
            elif b - a > 0.05 and not self.windows.active(a + offset) and not self.windows.active(b + offset):
                skipped = self.starved_skips(a + offset, b + offset)
                if b - a <= TICK_S * (skipped + 2):  # the rows around the gap, and a tick of timing slack
                    self.starved_gaps.append(f"log gap {b - a:.3f} s at rig time {a:.2f} s: {skipped} ticks "
                                             f"skipped in CPU-starved polls then")
                    continue
                self.counts["lost_log_rows"] += 1
                self.notes.append(f"log gap {b - a:.3f} s at rig time {a:.2f} s with no fault under way "
                                  f"({skipped} ticks skipped in CPU-starved polls then)")

    def starved_skips(self, a, b):
        """Ticks the rig counted as skipped in CPU-starved polls within 0.2 s of soak times a..b."""
        return sum(n for t0, t1, n in self.starved_spans if t0 - 0.2 <= b and a <= t1 + 0.2)

    def report(self):
        (self.work / "counts.json").write_text(json.dumps(
            {"seconds": self.args.seconds, "seed": self.args.seed, "faults": self.faults_fired,
             "watchdog_after_restart": self.watchdog_after_restart, "counts": self.counts}, indent=1) + "\n")
        print(f"faults fired: {json.dumps(self.faults_fired)}")
        print(f"watchdog register after each module restart: {self.watchdog_after_restart} "
              f"(want {WATCHDOG_MS} each)")
        print(f"log rows: {getattr(self, 'log_rows', 0)}; the machine short of CPU: a 5 ms sleep beside the rig "
              f"woke > 8 ms late {len(self.probe_late)} times; between two polls the rig or its module waited "
              f">= {RUN_WAIT_NS / 1e6:g} ms on a run queue {self.short['run_queue']} times, else the hypervisor stole "
              f">= {STEAL_JIFFIES * 10} ms {self.short['steal']} times, of {self.short['polls']}; "
              f"{self.starved_ticks} missed ticks then (not counted)")
        for n in self.starved_gaps[:10]:
            print("  (not counted) " + n)
        for n in self.notes[:40]:
            print("  " + n)
        width = max(len(k) for k in self.counts)
        for k, v in self.counts.items():
            print(f"  {k:<{width}}  {v}")
        bad = sum(self.counts.values())
        print("chaos soak: " + ("PASS (every count zero)" if bad == 0 else f"FAIL ({bad} in all)"), flush=True)
        return 0 if bad == 0 else 1


def main():
    logging.getLogger("pymodbus").setLevel(logging.CRITICAL)  # refused connections during restarts are expected
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--seconds", type=float, default=600)
    p.add_argument("--seed", type=int, default=23)
    p.add_argument("--work", required=True)
    p.add_argument("--progress", action="store_true")
    args = p.parse_args()
    for name, path in (("LEVELER_RIG", rp.RIG), ("LEVELER_PLANT_SERVER", rp.PLANT_SERVER), ("LEVELER_MBAPS", MBAPS)):
        if not path:
            p.error(f"{name} is not set")
    return Soak(args).run()


if __name__ == "__main__":
    sys.exit(main())

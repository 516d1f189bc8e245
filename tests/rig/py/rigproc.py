"""Process harness for the rig tests in Python: leveler-plant-server and
leveler-rig as child processes on 127.0.0.1 with kernel-chosen ports, each
wait bounded. Binaries and configs come from the environment CTest sets:
LEVELER_RIG, LEVELER_PLANT_SERVER, LEVELER_PLANT_CONFIG (thesis 900 lb),
LEVELER_STEADY_CONFIG (constant load)."""

from __future__ import annotations

import os
import signal
import subprocess
import time
from pathlib import Path

from pymodbus.client import ModbusTcpClient

RIG = os.environ.get("LEVELER_RIG", "")
PLANT_SERVER = os.environ.get("LEVELER_PLANT_SERVER", "")
PLANT_CONFIG = os.environ.get("LEVELER_PLANT_CONFIG", "")
STEADY_CONFIG = os.environ.get("LEVELER_STEADY_CONFIG", "")

# Register map addresses (docs/registers.md, generated from registers.json).
HR_MODE, MODE_MANUAL = 0, 2
COIL_CLEAR_FAULTS, COIL_MANUAL_COMPRESSOR, COIL_MANUAL_SPRING_VALVE = 0, 1, 2
DI_FAULT_LATCHED, DI_SENSORS_VALID, DI_LOG_FAULT = 5, 6, 9
IR_CONTROL_STATE, STATE_SAFE = 9, 3
IR_UPTIME_MS, IR_LOG_ROWS_DROPPED, IR_SENSOR_SCANS_FAILED = 18, 34, 36
# The plant server's module map (host_sim/rig/plant_server.c).
MODULE_HR_WATCHDOG_MS, MODULE_IR_WATCHDOG_TRIPS = 2, 5


def wait_until(predicate, timeout_s, step_s=0.01):
    """predicate()'s first true value, or None after timeout_s."""
    until = time.monotonic() + timeout_s
    while True:
        value = predicate()
        if value or time.monotonic() >= until:
            return value or None
        time.sleep(step_s)


def read_port(path: Path, proc: subprocess.Popen, timeout_s=20.0, output: Path = None) -> int:
    def ready():
        if proc.poll() is not None:
            said = output.read_text() if output and output.exists() else ""
            raise RuntimeError(f"{proc.args[0]} exited with {proc.returncode} before listening: {said}")
        try:
            return int(path.read_text().strip() or 0)
        except (OSError, ValueError):
            return 0
    port = wait_until(ready, timeout_s)
    if not port:
        raise RuntimeError(f"no port in {path} after {timeout_s} s")
    return port


def ini_text(sections: dict) -> str:
    return "".join(f"[{name}]\n" + "".join(f"{k} = {v}\n" for k, v in keys.items()) + "\n"
                   for name, keys in sections.items())


def u32(regs) -> int:
    return (regs[0] << 16) | regs[1]


class Plant:
    """leveler-plant-server: the plant served as a Modbus TCP I/O module."""

    def __init__(self, tmp: Path, config=STEADY_CONFIG, clock="realtime", port=0):
        """port: 0 = the kernel's choice; a restarted module takes its old port again."""
        self.tmp = tmp
        port_file = tmp / "plant.port"
        port_file.unlink(missing_ok=True)
        self.out = open(tmp / "plant.out", "a")
        self.proc = subprocess.Popen([PLANT_SERVER, "--config", str(config), "--port", str(port), "--port-file",
                                      str(port_file), "--clock", clock, "--max-seconds", "120"],
                                     stdout=self.out, stderr=subprocess.STDOUT)
        self.port = read_port(port_file, self.proc, output=tmp / "plant.out")

    def client(self) -> ModbusTcpClient:
        return connect(self.port)

    def stop(self):
        stop_process(self.proc)
        self.out.close()


class Rig:
    """leveler-rig with a config written from sections; overrides merge per section."""

    def __init__(self, tmp: Path, plant: Plant, clock="monotonic", overrides=None):
        self.tmp = tmp
        self.log_path = tmp / "rig.csv"
        self.config_path = tmp / "rig.ini"
        self.port_file = tmp / "supervision.port"
        sections = {
            "rig": {"name": "thesis-900lb", "clock": clock},
            "sensors": {"transport": "tcp", "host": "127.0.0.1", "port": plant.port,
                        "timeout_ms": 5 if clock == "monotonic" else 2000},
            "sensor.height": {"register": 0}, "sensor.p_spring": {"register": 1},
            "sensor.p_pipe": {"register": 2}, "sensor.p_acc": {"register": 3},
            "sensor.load": {"register": 4, "raw_lo": 0, "raw_hi": 1, "load_n_lo": 0, "load_n_hi": 1},
            "outputs": {"backend": "modbus"},
            "output.compressor": {"coil": 0}, "output.spring_valve": {"coil": 1},
            "output.vent_valve": {"coil": 2}, "output.acc_valve": {"coil": 3},
            "supervision": {"address": "127.0.0.1", "port": 0, "port_file": self.port_file},
            "log": {"path": self.log_path},
        }
        for name, keys in (overrides or {}).items():
            if keys is None:
                sections.pop(name, None)
            else:
                sections.setdefault(name, {}).update(keys)
        self.config_path.write_text(ini_text(sections))
        self.proc = None
        self.port = None

    def start(self, preexec_fn=None, env=None, wait_port=True):
        self.out = open(self.tmp / "rig.out", "w")
        self.proc = subprocess.Popen([RIG, "--config", str(self.config_path)], stdout=self.out,
                                     stderr=subprocess.STDOUT, preexec_fn=preexec_fn, env=env)
        if wait_port:
            self.port = read_port(self.port_file, self.proc, output=self.tmp / "rig.out")
        return self

    def client(self) -> ModbusTcpClient:
        return connect(self.port)

    def output(self) -> str:
        if not self.out.closed:
            self.out.flush()
        return (self.tmp / "rig.out").read_text()

    def stop(self):
        if self.proc is not None:
            stop_process(self.proc)
            self.out.close()


def connect(port, host="127.0.0.1", **kw) -> ModbusTcpClient:
    c = ModbusTcpClient(host, port=port, timeout=2, retries=0, **kw)
    if not c.connect():
        raise RuntimeError(f"cannot connect to {host}:{port}")
    return c


def stop_process(proc: subprocess.Popen, timeout_s=10.0):
    if proc.poll() is None:
        try:
            os.kill(proc.pid, signal.SIGCONT)
            proc.terminate()
            proc.wait(timeout_s)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()

"""leveler-monitor's Modbus side: one client (TCP to a rig, RTU to a board)
shared under a lock, a poller thread that reads the whole register map at up
to 10 Hz into a ring of samples, and the validated writes.

A refused write comes back as Modbus exception 03; the firmware then holds
why in the input register last_refusal_reason (docs/registers.md), read here
and named from registers.json.
"""
import collections
import sys
import threading
import time

from pymodbus.client import ModbusSerialClient, ModbusTcpClient
from pymodbus.exceptions import ModbusException

EXCEPTION_ILLEGAL_FUNCTION, EXCEPTION_ILLEGAL_ADDRESS, EXCEPTION_ILLEGAL_VALUE = 1, 2, 3
TABLE_READS = {"input": "read_input_registers", "holding": "read_holding_registers",
               "discrete": "read_discrete_inputs", "coil": "read_coils"}


class LinkError(Exception):
    """No answer, or an answer that is not the one asked for."""


class WriteRefused(Exception):
    """The firmware refused a write; reason is last_refusal_reason's name."""

    def __init__(self, what, reason):
        super().__init__(f"{what}: refused by the firmware: {reason}")
        self.reason = reason


def tcp_client(host, port, timeout_s):
    return ModbusTcpClient(host, port=port, timeout=timeout_s, retries=0)


def rtu_client(device, baud, parity, timeout_s):
    return ModbusSerialClient(device, baudrate=baud, parity=parity, bytesize=8, stopbits=1,
                              timeout=timeout_s, retries=0)


class Link:
    """One Modbus client, used by the poller and the page's writes in turn."""

    def __init__(self, client, regmap, device_id=1):
        self.client, self.regmap, self.device_id = client, regmap, device_id
        self.lock = threading.Lock()

    def _call(self, fn, *args, **kw):
        if not self.client.connected and not self.client.connect():
            raise LinkError("not connected")
        try:
            rr = getattr(self.client, fn)(*args, device_id=self.device_id, **kw)
        except (ModbusException, OSError) as e:   # pymodbus lets a reset connection's OSError through
            self.client.close()
            raise LinkError(str(e))
        return rr

    def read_all(self):
        """Every item of the map: {name: value in its unit}."""
        values = {}
        with self.lock:
            for table, fn in TABLE_READS.items():
                for start, count in self.regmap.read_spans(table):
                    rr = self._call(fn, start, count=count)
                    if rr.isError():
                        raise LinkError(f"{fn} {start}+{count}: {rr}")
                    words = rr.bits[:count] if table in ("discrete", "coil") else rr.registers
                    values.update(self.regmap.decode(table, start, words))
        return values

    def write(self, values):
        """Writes {name: value} of one table, contiguous, in one request (all or nothing)."""
        names = sorted(values, key=lambda n: self.regmap[n]["address"])
        table = self.regmap[names[0]]["table"]
        start, words = self.regmap[names[0]]["address"], []
        for n in names:
            if self.regmap[n]["table"] != table or self.regmap[n]["address"] != start + len(words):
                raise LinkError(f"{', '.join(names)}: not one contiguous block of one table")
            words += self.regmap.encode(n, values[n])
        with self.lock:
            if table == "coil":
                rr = self._call("write_coils", start, [bool(w) for w in words])
            else:
                rr = self._call("write_registers", start, words)
            if rr.isError():
                raise self._refusal(", ".join(names), rr)

    def _refusal(self, what, rr):
        code = getattr(rr, "exception_code", None)
        if code == EXCEPTION_ILLEGAL_FUNCTION:
            return LinkError(f"{what}: the server takes no writes from here (exception 01: a rig's "
                             f"[supervision] read_only or writers, or a certificate's role)")
        if code != EXCEPTION_ILLEGAL_VALUE:
            return LinkError(f"{what}: {rr}")
        reg = self.regmap["last_refusal_reason"]
        rr2 = self._call("read_input_registers", reg["address"], count=1)
        reason = "unknown (last_refusal_reason unreadable)" if rr2.isError() else \
            self.regmap.enum_name("last_refusal_reason", rr2.registers[0])
        return WriteRefused(what, reason)


def say(text):
    print(f"leveler-monitor: {text}", file=sys.stderr, flush=True)


class Poller(threading.Thread):
    """Reads the whole map every 1/rate_hz seconds into a ring of
    (seq, t, values); t is seconds since the poller started."""

    def __init__(self, link, rate_hz, keep=6000):
        super().__init__(name="leveler-monitor-poll", daemon=True)
        self.link, self.period = link, 1.0 / rate_hz
        self.samples = collections.deque(maxlen=keep)
        self.error = None           # the last read's failure, None while reads succeed
        self.seq = 0
        self._ring_lock = threading.Lock()      # the page's sessions read while this thread appends
        self._halt = threading.Event()
        self._t0 = time.monotonic()

    def run(self):
        next_at = time.monotonic()
        while not self._halt.is_set():
            try:
                values = self.link.read_all()
                with self._ring_lock:
                    self.seq += 1
                    self.samples.append((self.seq, time.monotonic() - self._t0, values))
                if self.error is not None:
                    say("link back")
                self.error = None
            except LinkError as e:
                if self.error is None:
                    say(f"link lost: {e}")
                self.error = str(e)
            next_at = max(next_at + self.period, time.monotonic())
            self._halt.wait(next_at - time.monotonic())

    def since(self, seq):
        """The samples newer than seq (all kept ones for seq 0)."""
        with self._ring_lock:
            return [s for s in self.samples if s[0] > seq]

    def stop(self):
        self._halt.set()

"""Processor in the loop: the emulated image (board.py) against the C plant
(plant.py), in lockstep on the emulator's clock.

* Commissioning is what an engineer does on a real rig: the holding registers
  for the config (the host firmware's commissioning, read back) are written
  over Modbus RTU on USART1; the image persists them to its flash store; the
  board is then power-cycled and the run starts from the stored settings.
* From the first control tick after that boot, every 10 ms of emulated time
  (on the SysTick edge, before its handler) the plant integrates one tick
  under the GPIOB outputs the image set, and its sensor values become the
  conversions the ADC's DMA writes into the image's buffer. The first tick
  runs under the config's [initial] actuators, as leveler-sim's does.
* A watchdog reset reboots the same image with RCC_CSR.IWDGRSTF set and the
  flash pages kept; the plant goes on.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field
from pathlib import Path

from elftools.elf.elffile import ELFFile
from pymodbus.framer.rtu import FramerRTU
from pymodbus.pdu.decoders import DecodePDU

from .board import UNITS_PER_S, Board
from .plant import Plant

ROOT = Path(__file__).resolve().parents[3]
DEFAULT_ELF = ROOT / "build/stm32f103/leveler.elf"
TICK_UNITS = UNITS_PER_S // 100          # 10 ms
POWER_ON_FLAGS = 0x0C00_0000             # RCC_CSR after power-on: PORRSTF | PINRSTF
IWDG_RESET_FLAGS = 0x2400_0000           # IWDGRSTF | PINRSTF
OUT_PINS = (12, 13, 14, 15)              # PB12..PB15: compressor, spring, vent, acc valve


class PilError(RuntimeError):
    pass


def elf_symbols(path):
    with open(path, "rb") as f:
        syms = ELFFile(f).get_section_by_name(".symtab")
        return {s.name: s["st_value"] for s in syms.iter_symbols() if s.name}


def register_address(table, name):
    """Address of a register in firmware/regmap/registers.json (the one source)."""
    with open(ROOT / "firmware/regmap/registers.json") as f:
        regs = json.load(f)["registers"]
    return next(r["address"] for r in regs if r["table"] == table and r["name"] == name)


def call_returns(path, target):
    """Addresses right after every `bl target` in .text (where the call returns)."""
    from capstone import CS_ARCH_ARM, CS_MODE_MCLASS, CS_MODE_THUMB, Cs
    with open(path, "rb") as f:
        text = ELFFile(f).get_section_by_name(".text")
        code, base = text.data(), text["sh_addr"]
    cs = Cs(CS_ARCH_ARM, CS_MODE_THUMB + CS_MODE_MCLASS)
    cs.skipdata = True
    return [i.address + i.size for i in cs.disasm(code, base)
            if i.mnemonic == "bl" and i.op_str == f"#0x{target & ~1:x}"]


@dataclass
class TickCost:
    """One control tick: leveler_app_tick() from entry to return."""
    t_s: float
    instructions: int        # the tick's own code, handlers excluded
    cycles: int              # estimated Cortex-M3 cycles of the same
    cycles_with_isr: int     # what a DWT read either side would see (handlers included)


@dataclass
class Trace:
    t_s: list = field(default_factory=list)
    state: list = field(default_factory=list)      # (height, P2, P1, P3, load)
    outputs: list = field(default_factory=list)    # (compressor, spring, vent, acc)


class Pil:
    def __init__(self, config=None, elf=DEFAULT_ELF, *, hse_ok=True):
        self.elf = Path(elf)
        if not self.elf.is_file():
            raise PilError(f"{self.elf}: no image (run `make firmware`)")
        self.syms = elf_symbols(self.elf)
        self.tick_returns = call_returns(self.elf, self.syms["leveler_app_tick"])
        self.plant = Plant(config) if config else None
        self.hse_ok = hse_ok
        self.settings = None
        self.board = None
        self.boots = []                     # (time_s, reset flags)
        self.resets = []                    # watchdog resets: (time_s, where the core was, anomalies)
        self.rx = bytearray()               # bytes the image sent on USART1
        self.serial_sink = None             # extra consumer of those bytes (the pty bridge)
        self.serial_source = None           # polled each ms for bytes to the image
        self.ticks = []                     # TickCost per control tick
        self.trace = Trace()
        self.plant_next = None              # master time of the next plant step
        self.plant_running = False
        self.adc_valid_from = 0             # master time the first scan set may complete
        self._tick_entry = None
        self.wall_s = 0.0
        self.boot(POWER_ON_FLAGS)

    # ---- boards ----
    @property
    def now(self):
        return self.board.now if self.board else 0

    @property
    def t_s(self):
        return self.now / UNITS_PER_S

    def boot(self, flags):
        """Power-on or reset: a new core and peripherals, flash pages kept."""
        if self.board is not None:
            self.settings = bytes(self.board.settings.data)
        counts = self.plant.sensor_counts(noisy=False) if self.plant else [2048, 2048, 2048, 2048]
        b = Board(self.elf, settings=self.settings, reset_flags=flags, hse_ok=self.hse_ok, now=self.now,
                  adc_counts=counts)
        b.on_systick = self._on_systick
        b.serial_out = self._serial_out
        b.adc_valid = self.now >= self.adc_valid_from
        b.hook_address(self.syms["leveler_app_tick"] & ~1, self._tick_entered)
        for ret in self.tick_returns:
            b.hook_address(ret, self._tick_returned)
        self.board = b
        self.boots.append((self.t_s, flags))
        self._tick_entry = None

    def run_for(self, seconds):
        self.run_until_units(self.now + int(seconds * UNITS_PER_S))

    def run_until_units(self, t_end):
        wall = time.perf_counter()
        try:
            while self.now < t_end:
                self.board.run_until(t_end, {})
                if self.board.reset_request:
                    b = self.board
                    self.resets.append((self.t_s, f"pc=0x{b.ql.arch.regs.pc:08x}", list(b.anomalies)))
                    self.boot(IWDG_RESET_FLAGS)
        finally:
            self.wall_s += time.perf_counter() - wall

    # ---- lockstep ----
    def outputs(self):
        odr = self.board.gpio_odr("b")
        return tuple(bool(odr >> p & 1) for p in OUT_PINS)

    def start_plant(self):
        """The plant runs from the next control tick on (t = 0 is the tick before it)."""
        self.plant_running = True
        self.plant_next = None

    def _tick_entered(self):
        b = self.board
        if self.plant_running and self.plant_next is None:
            # First tick: the plant's t = 10 ms is this SysTick edge; the tick
            # before it ran under the config's [initial] actuators.
            self._plant_step(self.outputs())      # the stepper applies [initial] at tick 0
            self.plant_next = b.systick.last + TICK_UNITS
        self._tick_entry = (b.instructions - b.isr_instructions, b.cycles, b.isr_instructions,
                            self._isr_cycles())

    def _isr_cycles(self):
        return self.board.isr_cycles

    def _tick_returned(self):
        if self._tick_entry is None:
            return
        b = self.board
        i0, c0, _, ic0 = self._tick_entry
        isr_c = self._isr_cycles() - ic0
        self.ticks.append(TickCost(self.t_s, b.instructions - b.isr_instructions - i0,
                                   b.cycles - c0 - isr_c, b.cycles - c0))
        self._tick_entry = None

    def _plant_step(self, outputs):
        st, applied = self.plant.step(outputs)
        self.trace.t_s.append(st[0])
        self.trace.state.append(st[1:])
        self.trace.outputs.append(applied)
        self.board.adc_counts[:] = self.plant.sensor_counts()
        self.board.dma1.write_conversions()

    def _on_systick(self):
        b = self.board
        if not b.adc_valid and self.now >= self.adc_valid_from:
            b.adc_valid = True
        if self.serial_source is not None:
            data = self.serial_source()
            if data:
                b.usart1.send(data)
        if self.plant_next is not None and b.systick.last >= self.plant_next:
            self._plant_step(self.outputs())
            self.plant_next += TICK_UNITS

    def _serial_out(self, data):
        self.rx += data
        if self.serial_sink is not None:
            self.serial_sink(data)

    # ---- Modbus master on the emulated bus ----
    def request(self, pdu, timeout_s=1.0):
        """Sends one request frame to USART1 and runs the board until the
        reply frame is complete; returns the reply PDU (or None on timeout)."""
        framer = FramerRTU(DecodePDU(False))
        self.rx.clear()
        self.board.usart1.send(framer.buildFrame(pdu))
        t_end = self.now + int(timeout_s * UNITS_PER_S)
        while self.now < t_end:
            self.run_until_units(min(t_end, self.now + UNITS_PER_S // 1000))
            if len(self.rx) >= 5:
                used, reply = framer.handleFrame(bytes(self.rx), 0, 0)
                if reply is not None:
                    return reply
        return None

    def wait_first_tick(self, limit_s=1.0):
        """Runs until the image's main loop has run a control tick (boot done)."""
        first = len(self.ticks)
        t_end = self.now + int(limit_s * UNITS_PER_S)
        while len(self.ticks) == first and self.now < t_end:
            self.run_until_units(min(t_end, self.now + UNITS_PER_S // 1000))
        if len(self.ticks) == first:
            raise PilError(f"no control tick within {limit_s} s of boot (pc=0x{self.board.ql.arch.regs.pc:08x})")

    def write_registers(self, addr, values):
        from pymodbus.pdu.register_message import WriteMultipleRegistersRequest
        reply = self.request(WriteMultipleRegistersRequest(address=addr, registers=list(values), dev_id=1))
        if reply is None or reply.isError():
            raise PilError(f"write of holding {addr}..{addr + len(values) - 1}: "
                           f"{'no reply' if reply is None else reply}")

    def read_registers(self, table, addr, count):
        from pymodbus.pdu.register_message import ReadHoldingRegistersRequest, ReadInputRegistersRequest
        cls = {"holding": ReadHoldingRegistersRequest, "input": ReadInputRegistersRequest}[table]
        reply = self.request(cls(address=addr, count=count, dev_id=1))
        if reply is None or reply.isError():
            raise PilError(f"read of {table} {addr}..{addr + count - 1}: {'no reply' if reply is None else reply}")
        return list(reply.registers)

    def read_u32_register(self, name):
        hi, lo = self.read_registers("input", register_address("input", name), 2)
        return hi << 16 | lo

    def write_coil(self, name, value):
        from pymodbus.pdu.bit_message import WriteSingleCoilRequest
        reply = self.request(WriteSingleCoilRequest(address=register_address("coil", name), bits=[bool(value)],
                                                    dev_id=1))
        if reply is None or reply.isError():
            raise PilError(f"write of coil {name}: {'no reply' if reply is None else reply}")

    def read_bits(self, name, count=1):
        from pymodbus.pdu.bit_message import ReadDiscreteInputsRequest
        reply = self.request(ReadDiscreteInputsRequest(address=register_address("discrete", name), count=count,
                                                       dev_id=1))
        if reply is None or reply.isError():
            raise PilError(f"read of discrete input {name}: {'no reply' if reply is None else reply}")
        return list(reply.bits[:count])

    def commission(self, algorithm=0, settle_s=1.5):
        """Writes the config's commissioning registers over Modbus, lets the
        image persist them (it saves 1 s after the last change), power-cycles
        the board and checks they came back from its flash store."""
        runs = self.plant.commission_registers(algorithm)
        self.wait_first_tick()
        for addr, values in runs:
            self.write_registers(addr, values)
        self.run_for(settle_s)
        self.boot(POWER_ON_FLAGS)
        self.wait_first_tick()
        for addr, values in runs:
            back = self.read_registers("holding", addr, len(values))
            if back != values:
                raise PilError(f"holding {addr}..: {back} after the power cycle, {values} written")

    def run_case(self, end_s=None):
        """Commissioned run of the config's scenario; returns the trace."""
        self.commission()
        self.start_plant()
        end = self.plant.end_s if end_s is None else end_s
        while not self.trace.t_s or self.trace.t_s[-1] < end - 1e-9:
            self.run_for(0.1)
        keep = sum(1 for t in self.trace.t_s if t <= end + 1e-9)
        for col in (self.trace.t_s, self.trace.state, self.trace.outputs):
            del col[keep:]
        return self.trace

"""The emulated STM32F103C8: Qiling loads the image and maps the chip; the
harness drives time and adds the peripheral behaviour the image needs.

Time: one master clock in units of 1/576 MHz (the least common multiple of
the 72, 64 and 8 MHz system clocks this board can run at). Executed code
advances it by its estimated Cortex-M3 cycles (``cycles.py``), counted per
translated block with ONE block hook, never per instruction. ``wfi`` (and a
branch-to-self spin) skips straight to the next event; a flash erase stalls
the core for its duration. Everything is deterministic: no wall clock.

Where Qiling 1.4.6's stm32f103 model lacks what the image needs, the harness
adds it here (docs: host_sim/pil/README.md, "Where the emulator needed help").
"""

from __future__ import annotations

import ctypes
import heapq
import logging

from qiling import Qiling
from qiling.const import QL_ARCH, QL_OS, QL_VERBOSE
from qiling.extensions.mcu.stm32f1 import stm32f103
from qiling.arch.cortex_m_const import EXCP
from unicorn import UC_HOOK_BLOCK, UC_HOOK_CODE, UC_HOOK_INTR
from unicorn.arm_const import (UC_ARM_REG_IPSR, UC_ARM_REG_LR, UC_ARM_REG_PC, UC_ARM_REG_R0, UC_ARM_REG_R1,
                               UC_ARM_REG_R2, UC_ARM_REG_R3, UC_ARM_REG_R12, UC_ARM_REG_SP, UC_ARM_REG_XPSR)

from . import cycles as cyc
from .periph import (Adc1, Dma1, FlashInterface, Iwdg, Nvic, Rcc, SettingsFlash, SysTick, Dwt,
                     Usart1, patch_gpio_brr)

UNITS_PER_S = 576_000_000
FLASH_BASE = 0x0800_0000
SETTINGS_BASE, SETTINGS_BYTES = 0x0800_F800, 2048
IRQ_DMA1_CH1, IRQ_USART1 = 11, 37
WFI = 0xBF30


class BoardError(RuntimeError):
    """The image did something the board cannot continue from (a lockup, an exception in the core)."""


class Board:
    """One power-on (or reset) of the chip. ``settings`` carries the two
    settings pages across resets; ``reset_flags`` the RCC_CSR reset cause."""

    def __init__(self, elf, *, settings=None, reset_flags=0x0C00_0000, hse_ok=True, now=0,
                 adc_counts=None):
        self.ql = Qiling([str(elf)], archtype=QL_ARCH.CORTEX_M, ostype=QL_OS.MCU, env=stm32f103,
                         verbose=QL_VERBOSE.DISABLED, log_plain=True)
        logging.getLogger("qiling").setLevel(logging.CRITICAL)
        self.uc = self.ql.uc
        self.now = now                 # master clock, 1/576 MHz units
        self.cycles = 0                # core cycles since this reset (DWT_CYCCNT source)
        self.instructions = 0          # executed instructions since this reset
        self.isr_instructions = 0
        self.isr_cycles = 0
        self._events = []              # heap of (time, seq, name)
        self._seq = 0
        self.in_isr = False
        self.idle = False
        self.frozen = False            # the core stalls on a flash that never finishes
        self.reset_request = None      # "iwdg" once the watchdog fired
        self.anomalies = []            # behaviour a real chip would not show / a board bug
        self._blocks = {}
        self._resume = None
        self._code_hooks = {}

        hw = self.ql.hw
        for label in ("gpioa", "gpiob", "gpioc", "afio"):
            hw.create(label)
        patch_gpio_brr(hw.gpioa, hw.gpiob, hw.gpioc)
        for label in ("systick", "nvic"):
            hw.delete(label)
        self.unit = UNITS_PER_S // 8_000_000   # master units per core cycle (HSI after reset)
        self.rcc = self._add("rcc", Rcc(self, hse_ok, reset_flags), 0x4002_1000, 0x400)
        self.nvic = self._add("nvic", Nvic(self), 0xE000_E100, 0xC00)
        self.systick = self._add("systick", SysTick(self), 0xE000_E010, 0x10)
        self.dwt = self._add("dwt", Dwt(self), 0xE000_1000, 0x10)
        self.iwdg = self._add("iwdg", Iwdg(self), 0x4000_3000, 0x400)
        self.adc1 = self._add("adc1", Adc1(self), 0x4001_2400, 0x400)
        self.dma1 = self._add("dma1", Dma1(self), 0x4002_0000, 0x400)
        self.usart1 = self._add("usart1", Usart1(self), 0x4001_3800, 0x400)
        self.flash_if = self._add("flash interface", FlashInterface(self), 0x4002_2000, 0x400)
        self.settings = SettingsFlash(self, settings)
        self.ql.mem.unmap(SETTINGS_BASE, SETTINGS_BYTES)
        self.ql.mem.map_mmio(SETTINGS_BASE, SETTINGS_BYTES, self.settings.read, self.settings.write,
                             info="[settings pages]")
        self.adc_counts = list(adc_counts or (0, 0, 0, 0))
        self.adc_valid = True          # False: the DMA never completes a scan set (sensors absent)
        self.on_systick = lambda: None  # the runner's lockstep point (before the handler runs)
        self.serial_out = lambda data: None

        self.uc.hook_add(UC_HOOK_BLOCK, self._on_block)
        self._exc_exit = False
        self.uc.hook_add(UC_HOOK_INTR, self._on_intr)
        self.ql.arch.init_context()
        self.reset_vector = self.ql.mem.read_ptr(4)
        self.initial_sp = self.ql.mem.read_ptr(0)

    # ---- peripherals and events ----
    def _add(self, label, model, base, size):
        model.base = base
        self.ql.hw.entity[label] = model
        self.ql.hw.region[label] = [(base, base + size)]
        return model

    def schedule(self, when, name):
        self._seq += 1
        heapq.heappush(self._events, (when, self._seq, name))

    def cancel(self, name):
        self._events = [e for e in self._events if e[2] != name]
        heapq.heapify(self._events)

    def next_event_time(self):
        return self._events[0][0] if self._events else None

    def clock_changed(self):
        """RCC switched the system clock: re-derive the units per core cycle
        (kept in an attribute: the block hook reads it for every block)."""
        self.unit = UNITS_PER_S // self.rcc.sysclk_hz
        self.systick.clock_changed()

    def advance(self, units):
        self.now += units
        self.cycles += units // self.unit

    # ---- code ----
    def _on_block(self, uc, addr, size, _):
        info = self._blocks.get(addr)
        if info is None:
            info = self._blocks[addr] = self._analyse(addr, size)
        n, c, spin, in_it = info
        if not self.in_isr and not in_it and (self._events and self.now >= self._events[0][0]):
            self._stop_at(uc, addr)    # an event is due: take it before this block
            return
        if spin and not self.in_isr and not in_it:   # b . : nothing changes until an interrupt
            self.idle = True
            self._stop_at(uc, addr)
            return
        self.instructions += n
        if self.in_isr:
            self.isr_instructions += n
            self.isr_cycles += c
        self.cycles += c
        self.now += c * self.unit

    def _analyse(self, addr, size):
        lo = max(FLASH_BASE, addr - 16) if addr >= FLASH_BASE else max(0, addr - 16)
        before = self.uc.mem_read(lo, addr - lo) if addr > lo else b""
        return cyc.analyse_block(self.uc.mem_read(addr, size), addr) + (cyc.starts_in_it_block(before, addr),)

    def _stop_at(self, uc, addr):
        """Stops before the block at addr runs (a stop requested in a block
        hook keeps that block from executing). The caller resumes at addr:
        unicorn 2.0.1 leaves a stale PC after a stop inside chained blocks."""
        self._resume = addr
        uc.emu_stop()

    def hook_address(self, addr, callback):
        """A code hook on one address (only that instruction pays for it)."""
        self.uc.hook_add(UC_HOOK_CODE, lambda uc, a, s, _: callback(), begin=addr, end=addr)

    def _fire_due(self, handlers):
        while self._events and self._events[0][0] <= self.now:
            _, _, name = heapq.heappop(self._events)
            handlers[name]()

    def run_until(self, t_end, handlers):
        """Runs the core and the peripherals until the master clock reaches
        t_end (or the watchdog resets the chip). handlers maps event names to
        callables (the board's own are added here)."""
        handlers = {**self._own_handlers(), **handlers}
        while self.now < t_end and self.reset_request is None:
            self._fire_due(handlers)
            if self.reset_request is not None:
                break
            if self.nvic.deliver():
                self.idle = False
            nxt = self.next_event_time()
            if self.frozen or (self.idle and not self.nvic.pending_deliverable()):
                self.advance(max(0, min(nxt if nxt is not None else t_end, t_end) - self.now))
                continue
            self.idle = False
            pc = self._resume_pc()
            self._resume = None
            try:
                self.uc.emu_start(pc | 1, 0, 0, 0)
            except Exception as e:  # an exception the core model could not take
                raise BoardError(f"core stopped at pc=0x{self.ql.arch.regs.pc:08x}: {e}") from e
            if self._exc_exit:
                self._exc_exit = False
                self._exception_return()
            elif self._resume is not None:
                self.uc.reg_write(UC_ARM_REG_PC, self._resume)
            else:
                pc = self.ql.arch.regs.pc
                if int.from_bytes(self.uc.mem_read(pc - 2, 2), "little") == WFI:
                    self.idle = True

    def _own_handlers(self):
        return {"systick": self.systick.fire, "adc_scan": self.dma1.scan_complete,
                "usart_rx": self.usart1.rx_due, "usart_tx": self.usart1.tx_done,
                "iwdg": self.iwdg.expire}

    # ---- the harness's view ----
    _FRAME = (UC_ARM_REG_R0, UC_ARM_REG_R1, UC_ARM_REG_R2, UC_ARM_REG_R3, UC_ARM_REG_R12,
              UC_ARM_REG_LR, UC_ARM_REG_PC, UC_ARM_REG_XPSR)

    def take_interrupt(self, intno):
        """Exception entry (ARMv7-M B1.5.6): 8-word frame on the main stack
        (8-byte aligned, bit 9 of the stacked xPSR says so), IPSR, LR =
        EXC_RETURN, PC = vector. The handler then runs in the ordinary
        emulation; its return raises EXCEPTION_EXIT and _exception_return
        unstacks. (Qiling's own entry runs each handler in a nested
        emu_start with an instruction count, and every such call makes
        unicorn 2.0.1 throw away all translated code: ~20 ms per interrupt.)"""
        uc = self.uc
        regs = [uc.reg_read(r) for r in self._FRAME]
        regs[6] = self._resume_pc()
        sp = uc.reg_read(UC_ARM_REG_SP)
        pad = sp & 4
        sp = (sp - pad - 32) & 0xFFFF_FFFF
        if pad:
            regs[7] |= 1 << 9
        self.write_mem(sp, b"".join(v.to_bytes(4, "little") for v in regs))
        uc.reg_write(UC_ARM_REG_SP, sp)
        uc.reg_write(UC_ARM_REG_IPSR, intno + 16)
        uc.reg_write(UC_ARM_REG_LR, 0xFFFF_FFF9)
        uc.reg_write(UC_ARM_REG_PC, self.read_u32(4 * (intno + 16)) & ~1)
        self._resume = None
        self.in_isr = True
        self.advance(12 * self.unit)

    def _resume_pc(self):
        return self._resume if self._resume is not None else self.uc.reg_read(UC_ARM_REG_PC)

    def _on_intr(self, uc, intno, _):
        if intno == EXCP.EXCEPTION_EXIT:
            self._exc_exit = True
        uc.emu_stop()

    def _exception_return(self):
        uc = self.uc
        sp = uc.reg_read(UC_ARM_REG_SP)
        frame = [self.read_u32(sp + 4 * k) for k in range(8)]
        uc.reg_write(UC_ARM_REG_IPSR, 0)
        for reg, v in zip(self._FRAME[:6], frame[:6]):
            uc.reg_write(reg, v)
        uc.reg_write(UC_ARM_REG_XPSR, frame[7] & ~(1 << 9) & ~0x1FF)
        uc.reg_write(UC_ARM_REG_SP, sp + 32 + (4 if frame[7] & (1 << 9) else 0))
        uc.reg_write(UC_ARM_REG_PC, frame[6] & ~1)
        self._resume = frame[6] & ~1
        self.in_isr = False
        self.advance(12 * self.unit)
        self.refresh_irq_levels()

    def refresh_irq_levels(self):
        self.usart1.update_irq()
        self.dma1.update_irq()

    @property
    def primask(self):
        return self.ql.arch.regs.read("primask") & 1

    def gpio_odr(self, port):
        return getattr(self.ql.hw, "gpio" + port).instance.ODR

    def read_u32(self, addr):
        return int.from_bytes(self.uc.mem_read(addr, 4), "little")

    def write_mem(self, addr, data):
        self.uc.mem_write(addr, bytes(data))

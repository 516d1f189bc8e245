"""Peripheral behaviour the image needs and Qiling 1.4.6's stm32f103 model
lacks or steps once per instruction (which is what makes it ~50k instr/s).
These are event driven on the board's master clock instead. Register layouts
and bits: RM0008 (RCC 7.3, GPIO 9.2, ADC 11.12, DMA 13.4, IWDG 19.4,
USART 27.6), PM0075 (flash), ARMv7-M ARM (SysTick, NVIC, DWT).
Each model has ``base`` and ``read(offset, size)`` / ``write(offset, size, value)``
as Qiling's MMIO dispatch expects of a peripheral.
"""

from __future__ import annotations

from collections import deque

from qiling.arch.cortex_m_const import IRQ

UNITS_PER_S = 576_000_000
HSI_HZ = HSE_HZ = 8_000_000
LSI_HZ = 40_000                     # nominal (30..60 kHz over parts and temperature)
SYSTICK_EXC = int(IRQ.SYSTICK)      # -1
HARD_FAULT_EXC = int(IRQ.HARD_FAULT)


class Regs:
    """A block of 32-bit registers; subclasses give the special behaviour."""
    count = 16

    def __init__(self, board):
        self.board = board
        self.r = [0] * self.count
        self.base = 0

    def read(self, offset, size):
        v = self.get(offset // 4)
        return (v >> (8 * (offset % 4))) & ((1 << (8 * size)) - 1)

    def write(self, offset, size, value):
        if size != 4:  # byte/halfword writes to a word register: merge
            shift = 8 * (offset % 4)
            mask = ((1 << (8 * size)) - 1) << shift
            value = (self.r[offset // 4] & ~mask) | ((value << shift) & mask)
        self.put(offset // 4, value & 0xFFFF_FFFF)

    def get(self, i):
        return self.r[i] if i < self.count else 0

    def put(self, i, v):
        if i < self.count:
            self.r[i] = v


class Rcc(Regs):
    """Ready flags follow their enables at once (HSERDY only when a crystal is
    fitted: hse_ok=False is a dead or missing crystal); SWS follows SW when the
    source is ready; RMVF clears the reset flags."""
    CR, CFGR, CIR, AHBENR, APB2ENR, CSR = 0, 1, 2, 5, 6, 9

    def __init__(self, board, hse_ok, reset_flags):
        super().__init__(board)
        self.hse_ok = hse_ok
        self.r[self.CR] = 0x0000_0083
        self.r[self.AHBENR] = 0x14
        self.r[self.CSR] = reset_flags

    def get(self, i):
        if i == self.CR:
            cr = self.r[self.CR] & ~((1 << 1) | (1 << 17) | (1 << 25))
            if cr & 1:
                cr |= 1 << 1
            if cr & (1 << 16) and self.hse_ok:
                cr |= 1 << 17
            if cr & (1 << 24) and self._pll_source_ready():
                cr |= 1 << 25
            return cr
        if i == self.CFGR:
            return (self.r[self.CFGR] & ~0xC) | (self._sws() << 2)
        return super().get(i)

    def put(self, i, v):
        if i == self.CSR and v & (1 << 24):
            v &= ~0xFC00_0000 & ~(1 << 24)
        old_clock = self.sysclk_hz if i in (self.CR, self.CFGR) else None
        super().put(i, v)
        if old_clock is not None and self.sysclk_hz != old_clock:
            self.board.clock_changed()

    def _pll_source_ready(self):
        return not (self.r[self.CFGR] >> 16) & 1 or ((self.r[self.CR] >> 16) & 1 and self.hse_ok)

    def _sws(self):
        sw = self.r[self.CFGR] & 3
        cr = self.get(self.CR)
        ready = {0: cr & (1 << 1), 1: cr & (1 << 17), 2: cr & (1 << 25)}.get(sw, 0)
        return sw if ready else 0

    @property
    def sysclk_hz(self):
        sws = self._sws()
        if sws == 1:
            return HSE_HZ
        if sws == 2:
            cfgr = self.r[self.CFGR]
            src = HSE_HZ if (cfgr >> 16) & 1 else HSI_HZ // 2
            return src * min(((cfgr >> 18) & 0xF) + 2, 16)
        return HSI_HZ

    @property
    def adc_hz(self):
        return self.sysclk_hz // (2 * (((self.r[self.CFGR] >> 14) & 3) + 1))


class Nvic(Regs):
    """Enable and pending bits, and delivery in exception-number order (this
    board uses one priority level, so handlers never nest). Level-triggered
    sources (USART, DMA) are re-sampled after every handler."""
    count = 0x300 // 4

    def __init__(self, board):
        super().__init__(board)
        self.enabled = set()
        self.pending = set()

    def get(self, i):
        bank = i % 32
        group = i // 32
        src = {0: self.enabled, 2: self.pending}.get(group)
        if src is None or bank >= 8:
            return 0
        return sum(1 << (n - 32 * bank) for n in src if 32 * bank <= n < 32 * bank + 32)

    def put(self, i, v):
        bank, group = i % 32, i // 32
        if bank >= 8 or group > 3:
            return
        irqs = {32 * bank + b for b in range(32) if v >> b & 1}
        if group == 0:
            self.enabled |= irqs
            self.board.refresh_irq_levels()
        elif group == 1:
            self.enabled -= irqs
        elif group == 2:
            self.pending |= irqs
        else:
            self.pending -= irqs

    def set_pending(self, n):
        self.pending.add(int(n))

    def _deliverable(self):
        masked = self.board.primask
        ready = [n for n in self.pending
                 if (n < 0 or n in self.enabled) and (not masked or n <= HARD_FAULT_EXC)]
        return min(ready) if ready else None

    def pending_deliverable(self):
        return self._deliverable() is not None

    def deliver(self):
        """Enters the most urgent deliverable exception; its handler then runs
        in the ordinary emulation. One at a time: handlers do not nest on this
        board (one priority level), except a fault inside a handler."""
        n = self._deliverable()
        if n is None or (self.board.in_isr and n != HARD_FAULT_EXC):
            return False
        self.pending.discard(n)
        if n == HARD_FAULT_EXC:
            self.board.anomalies.append(f"hard fault near pc=0x{self.board.ql.arch.regs.pc:08x}")
        self.board.take_interrupt(n)
        return True


class SysTick(Regs):
    """Counts core cycles (CLKSOURCE = 1) or HCLK/8; one pending bit however
    many reloads a stall covered, as on the chip."""
    CTRL, LOAD, VAL = 0, 1, 2
    count = 4

    def __init__(self, board):
        super().__init__(board)
        self.r[3] = 0x4000_0000 | 9000   # CALIB: TENMS for 72 MHz / 8
        self.last = 0
        self.next = None

    def period(self):
        div = 1 if self.r[self.CTRL] & 4 else 8
        return (self.r[self.LOAD] + 1) * div * self.board.unit

    def _restart(self):
        self.board.cancel("systick")
        self.next = None
        if self.r[self.CTRL] & 1 and self.r[self.LOAD]:
            self.last = self.board.now
            self.next = self.last + self.period()
            self.board.schedule(self.next, "systick")

    def clock_changed(self):
        if self.next is not None:
            self._restart()

    def get(self, i):
        if i == self.VAL:
            if self.next is None:
                return 0
            return max(0, (self.next - self.board.now) // self.board.unit) & 0xFFFFFF
        if i == self.CTRL:
            v = self.r[self.CTRL]
            self.r[self.CTRL] &= ~(1 << 16)
            return v
        return super().get(i)

    def put(self, i, v):
        if i == self.CTRL:
            was = self.r[self.CTRL] & 1
            self.r[self.CTRL] = v & 7
            if (v & 1) != was:
                self._restart()
        elif i == self.LOAD:
            self.r[self.LOAD] = v & 0xFFFFFF
        elif i == self.VAL:
            self.r[self.CTRL] &= ~(1 << 16)
            if self.r[self.CTRL] & 1:
                self._restart()

    def fire(self):
        self.r[self.CTRL] |= 1 << 16
        if self.r[self.CTRL] & 2:
            self.board.nvic.set_pending(SYSTICK_EXC)
        p = self.period()
        self.last = self.next
        self.next += p
        if self.next <= self.board.now:  # a stall covered several reloads: one pending bit
            missed = (self.board.now - self.next) // p + 1
            self.last += missed * p
            self.next += missed * p
        self.board.schedule(self.next, "systick")
        self.board.on_systick()


class Dwt(Regs):
    """CYCCNT from the board's cycle estimate (the same count the tick cost uses)."""
    count = 4

    def __init__(self, board):
        super().__init__(board)
        self.origin = 0

    def get(self, i):
        if i == 1:
            return (self.board.cycles - self.origin) & 0xFFFF_FFFF if self.r[0] & 1 else 0
        return super().get(i)

    def put(self, i, v):
        if i == 1:
            self.origin = self.board.cycles - v
        else:
            super().put(i, v)


class Iwdg(Regs):
    """Keys 0xCCCC start, 0xAAAA reload, 0x5555 unlocks PR/RLR; once started it
    cannot be stopped. Expiry resets the chip (the runner reboots the image
    with RCC_CSR.IWDGRSTF set)."""
    KR, PR, RLR, SR = 0, 1, 2, 3
    count = 4

    def __init__(self, board):
        super().__init__(board)
        self.r[self.RLR] = 0xFFF
        self.running = False
        self.unlocked = False
        self.refreshes = 0

    def timeout_units(self):
        return self.r[self.RLR] * (4 << (self.r[self.PR] & 7)) * UNITS_PER_S // LSI_HZ

    def _reload(self):
        self.board.cancel("iwdg")
        self.board.schedule(self.board.now + self.timeout_units(), "iwdg")

    def get(self, i):
        return 0 if i == self.SR else super().get(i)   # PVU/RVU: updates take effect at once

    def put(self, i, v):
        if i == self.KR:
            key = v & 0xFFFF
            self.unlocked = key == 0x5555
            if key == 0xCCCC:
                self.running = True
                self._reload()
            elif key == 0xAAAA and self.running:
                self.refreshes += 1
                self._reload()
        elif i in (self.PR, self.RLR) and self.unlocked:
            self.r[i] = v & (7 if i == self.PR else 0xFFF)

    def expire(self):
        self.board.reset_request = "iwdg"


class Adc1(Regs):
    """Register file with calibration finishing at once; continuous scan with
    DMA is carried out by Dma1 on the scan-set period."""
    SR, CR1, CR2, SMPR1, SMPR2, SQR1, SQR2, SQR3, DR = 0, 1, 2, 3, 4, 11, 12, 13, 19
    count = 20
    SAMPLE_HALF_CYCLES = (3, 15, 27, 57, 83, 111, 143, 479)   # 1.5 .. 239.5 ADC clocks, x2

    def put(self, i, v):
        if i == self.CR2:
            swstart = v & (1 << 22)
            v &= ~((1 << 2) | (1 << 3) | (1 << 22))   # CAL, RSTCAL done; SWSTART self-clears
            self.r[i] = v
            if swstart and v & 1 and v & (1 << 8):     # ADON + DMA: conversions start
                self.board.dma1.adc_running()
            return
        super().put(i, v)

    def sequence(self):
        n = ((self.r[self.SQR1] >> 20) & 0xF) + 1
        regs = (self.r[self.SQR3], self.r[self.SQR2], self.r[self.SQR1])
        return [(regs[k // 6] >> (5 * (k % 6))) & 0x1F for k in range(n)]

    def conversion_units(self, channel):
        smpr = self.r[self.SMPR2] if channel < 10 else self.r[self.SMPR1]
        code = (smpr >> (3 * (channel % 10))) & 7
        half = self.SAMPLE_HALF_CYCLES[code] + 25      # + 12.5 conversion clocks
        return half * UNITS_PER_S // (2 * self.board.rcc.adc_hz)


class Dma1(Regs):
    """Channel 1 only (ADC1): at every completed circular pass (a "scan set")
    the conversions are written to CMAR, TCIF1/HTIF1/GIF1 raised; IFCR clears."""
    ISR, IFCR = 0, 1
    count = 2 + 5 * 7

    def __init__(self, board):
        super().__init__(board)
        self.running = False
        self.count_at_enable = 0

    def _ch1(self, k):
        return self.r[2 + k]

    def put(self, i, v):
        if i == self.ISR:
            return
        if i == self.IFCR:
            for ch in range(7):
                if v >> (4 * ch) & 1:
                    v |= 0xF << (4 * ch)
            self.r[self.ISR] &= ~v
            return
        if i == 2 and v & 1 and not self.r[2] & 1:
            self.count_at_enable = self.r[3]
        super().put(i, v)

    def adc_running(self):
        if not self.running:
            self.running = True
            self.board.schedule(self.board.now + self.scan_set_units(), "adc_scan")

    def scan_set_units(self):
        adc = self.board.adc1
        seq = adc.sequence()
        passes = max(1, (self._ch1(1) or 1) // len(seq))
        return passes * sum(adc.conversion_units(c) for c in seq)

    def write_conversions(self):
        """The current conversions into the whole circular buffer (what DMA
        writes over one scan set while the inputs hold still)."""
        if not (self.r[2] & 1 and self.running):
            return
        adc = self.board.adc1
        seq = adc.sequence()
        n = self.count_at_enable
        data = bytearray()
        for k in range(n):
            data += int(self.board.adc_counts[seq[k % len(seq)]] & 0xFFF).to_bytes(2, "little")
        self.board.write_mem(self.r[2 + 3], data)

    def scan_complete(self):
        if self.r[2] & 1 and self.board.adc_valid:
            self.write_conversions()
            self.r[self.ISR] |= 0b0111            # GIF1, TCIF1, HTIF1
            self.update_irq()
        self.board.schedule(self.board.now + self.scan_set_units(), "adc_scan")

    def update_irq(self):
        ccr = self.r[2]
        isr = self.r[self.ISR]
        if (ccr & 2 and isr & 2) or (ccr & 8 and isr & 8) or (ccr & 4 and isr & 4):
            self.board.nvic.set_pending(11)


class Usart1(Regs):
    """Byte-level USART with the real timing (11 bit times per 8E1 character
    at the BRR rate), a transmit holding + shift register, RXNE/ORE/TXE/TC
    flags and a level interrupt. Bytes go to board.serial_out; bytes for the
    image are queued with send() and arrive one character time apart."""
    SR, DR, BRR, CR1 = 0, 1, 2, 3
    count = 7

    def __init__(self, board):
        super().__init__(board)
        self.r[self.SR] = 0xC0
        self.rx = deque()
        self.rx_scheduled = False
        self.shifting = None
        self.hold = None

    def char_units(self):
        bits = 11 if self.r[self.CR1] & (1 << 12) else 10
        return bits * max(self.r[self.BRR], 16) * self.board.unit

    def send(self, data):
        self.rx.extend(data)
        if not self.rx_scheduled and self.rx:
            self.rx_scheduled = True
            self.board.schedule(self.board.now + self.char_units(), "usart_rx")

    def rx_due(self):
        self.rx_scheduled = False
        if not self.rx:
            return
        byte = self.rx.popleft()
        if self.board.gpio_odr("a") >> 8 & 1:
            self.board.anomalies.append("byte arrived while the RS-485 driver was enabled (DE high): lost")
        elif self.r[self.CR1] & (1 << 13) and self.r[self.CR1] & (1 << 2):
            if self.r[self.SR] & (1 << 5):
                self.r[self.SR] |= 1 << 3           # overrun: the new byte is lost
            else:
                self.rx_dr = byte
                self.r[self.SR] |= 1 << 5
        if self.rx:
            self.rx_scheduled = True
            self.board.schedule(self.board.now + self.char_units(), "usart_rx")
        self.update_irq()

    def get(self, i):
        if i == self.DR:
            self.r[self.SR] &= ~((1 << 5) | 0xF)
            self.update_irq()
            return getattr(self, "rx_dr", 0)
        return super().get(i)

    def put(self, i, v):
        if i == self.SR:
            self.r[self.SR] &= v | ~((1 << 6) | (1 << 5))
        elif i == self.DR:
            self._transmit(v & 0xFF)
        else:
            super().put(i, v)
        self.update_irq()

    def _transmit(self, byte):
        if not (self.r[self.CR1] & (1 << 13) and self.r[self.CR1] & (1 << 3)):
            return
        if not self.board.gpio_odr("a") >> 8 & 1:
            self.board.anomalies.append("byte transmitted with the RS-485 driver disabled (DE low)")
        self.r[self.SR] &= ~(1 << 6)
        if self.shifting is None:
            self.shifting = byte
            self.board.schedule(self.board.now + self.char_units(), "usart_tx")
        else:
            self.hold = byte
            self.r[self.SR] &= ~(1 << 7)

    def tx_done(self):
        self.board.serial_out(bytes([self.shifting]))
        if self.hold is not None:
            self.shifting, self.hold = self.hold, None
            self.r[self.SR] |= 1 << 7
            self.board.schedule(self.board.now + self.char_units(), "usart_tx")
        else:
            self.shifting = None
            self.r[self.SR] |= 1 << 6
        self.update_irq()

    def update_irq(self):
        sr, cr1 = self.r[self.SR], self.r[self.CR1]
        if ((cr1 & (1 << 5) and sr & ((1 << 5) | (1 << 3))) or (cr1 & (1 << 7) and sr & (1 << 7))
                or (cr1 & (1 << 6) and sr & (1 << 6))):
            self.board.nvic.set_pending(37)


class FlashInterface(Regs):
    """Unlock keys, page erase (PER + AR + STRT) and halfword programming (PG)
    with EOP/PGERR; the core stalls for the operation (20 ms erase, 52 us
    halfword, PM0075 / DS5319). stuck_busy = a flash that never finishes."""
    ACR, KEYR, SR, CR, AR = 0, 1, 3, 4, 5
    count = 9
    ERASE_S, PROGRAM_S = 0.020, 52e-6

    def __init__(self, board):
        super().__init__(board)
        self.locked = True
        self.key1 = False
        self.stuck_busy = False
        self.erases = 0
        self.programs = 0

    def get(self, i):
        if i == self.CR:
            return self.r[self.CR] | (0x80 if self.locked else 0)
        if i == self.SR:
            return self.r[self.SR] | (1 if self.stuck_busy and self.board.frozen else 0)
        return super().get(i)

    def put(self, i, v):
        if i == self.KEYR:
            if not self.key1 and v == 0x4567_0123:
                self.key1 = True
            elif self.key1 and v == 0xCDEF_89AB:
                self.locked, self.key1 = False, False
            else:
                self.key1 = False
        elif i == self.SR:
            self.r[self.SR] &= ~(v & 0x34)
        elif i == self.CR:
            if v & 0x80:
                self.locked = True
            if self.locked:
                return
            self.r[self.CR] = v & 0x7F
            if v & 2 and v & 0x40:
                self._erase(self.r[self.AR])
        else:
            super().put(i, v)

    def _busy(self, seconds):
        if self.stuck_busy:
            self.board.frozen = True
            self.board.uc.emu_stop()
            return
        self.board.advance(int(seconds * UNITS_PER_S))
        self.r[self.SR] |= 0x20

    def _erase(self, addr):
        self.erases += 1
        if not self.board.settings.erase(addr):
            self.board.anomalies.append(f"page erase of 0x{addr:08x} outside the settings pages")
            self.r[self.SR] |= 0x10
            return
        self._busy(self.ERASE_S)

    def program(self, offset, size, value):
        if self.locked or not self.r[self.CR] & 1:
            self.board.anomalies.append(f"flash write at settings+0x{offset:x} without PG (ignored)")
            return False
        if size != 2:
            self.board.anomalies.append(f"flash programmed with a {size}-byte access (PM0075: halfwords)")
            self.r[self.SR] |= 0x04
            return False
        self.programs += 1
        if self.board.settings.halfword(offset) != 0xFFFF and value != 0:
            self.r[self.SR] |= 0x04
            return False
        self._busy(self.PROGRAM_S)
        return True


class SettingsFlash:
    """The two settings pages as memory-mapped flash: reads come from the
    array, writes only through the flash interface's programming."""
    BASE, PAGE, SIZE = 0x0800_F800, 1024, 2048

    def __init__(self, board, data=None):
        self.board = board
        self.data = bytearray(data) if data is not None else bytearray(b"\xff" * self.SIZE)

    def read(self, ql, offset, size):
        return int.from_bytes(self.data[offset:offset + size], "little")

    def write(self, ql, offset, size, value):
        if self.board.flash_if.program(offset, size, value):
            self.data[offset:offset + 2] = (value & 0xFFFF).to_bytes(2, "little")

    def halfword(self, offset):
        return int.from_bytes(self.data[offset:offset + 2], "little")

    def erase(self, addr):
        off = addr - self.BASE
        if not 0 <= off < self.SIZE:
            return False
        page = off // self.PAGE * self.PAGE
        self.data[page:page + self.PAGE] = b"\xff" * self.PAGE
        return True


def patch_gpio_brr(*ports):
    """Qiling's STM32F1xxGpio stores a BRR write as a plain register; on the
    F1 a 1 in BRR resets that ODR bit (RM0008 9.2.6). The image switches its
    outputs off through BRR."""
    for gpio in ports:
        write = gpio.write

        def patched(offset, size, value, gpio=gpio, write=write):
            if offset == 0x14:
                for pin in range(16):
                    if value >> pin & 1:
                        gpio.reset_pin(pin)
                return
            write(offset, size, value)
        gpio.write = patched

"""Boot checks of the flashable image under the emulator: vector table and
reset handler, clock set-up with and without the crystal, outputs safe until
the sensors are valid, the watchdog, settings through the flash store.
Expectations come from the datasheet / reference manual and the register
map, not from the harness."""

from elftools.elf.elffile import ELFFile

from leveler_pil.board import UNITS_PER_S
from leveler_pil.run import IWDG_RESET_FLAGS, POWER_ON_FLAGS, Pil, register_address

RAM_TOP = 0x2000_0000 + 20 * 1024           # STM32F103C8: 20 KB SRAM (DS5319 table 2)
OUT_MASK = 0xF << 12                        # PB12..PB15


def boot(elf, **kw):
    pil = Pil(None, elf, **kw)
    pil.wait_first_tick()
    return pil


def test_vector_table_and_reset_handler(elf):
    with open(elf, "rb") as f:
        e = ELFFile(f)
        syms = {s.name: s["st_value"] for s in e.get_section_by_name(".symtab").iter_symbols()}
        vec = e.get_section_by_name(".isr_vector")
        assert vec["sh_addr"] == 0x0800_0000, "the vector table must sit at the start of flash"
        words = [int.from_bytes(vec.data()[4 * k:4 * k + 4], "little") for k in range(16 + 43)]
    assert words[0] == RAM_TOP
    assert words[1] == syms["Reset_Handler"] | 1       # Thumb bit set
    assert words[15] == syms["SysTick_Handler"] | 1
    assert words[16 + 11] == syms["DMA1_Channel1_IRQHandler"] | 1
    assert words[16 + 37] == syms["USART1_IRQHandler"] | 1
    pil = Pil(None, elf)
    assert pil.board.reset_vector == syms["Reset_Handler"] | 1 and pil.board.initial_sp == RAM_TOP
    pil.wait_first_tick()                               # reached the main loop and ran a tick


def test_clock_with_crystal(elf):
    pil = boot(elf)
    assert pil.board.rcc.sysclk_hz == 72_000_000
    assert pil.board.systick.r[1] == 72_000_000 // 1000 - 1
    assert pil.read_bits("clock_fault") == [False]
    n = len(pil.ticks)
    pil.run_for(1.0)
    assert len(pil.ticks) - n in (99, 100, 101)         # one control tick per 10 ms


def test_clock_without_crystal_falls_back_to_hsi(elf):
    pil = boot(elf, hse_ok=False)
    assert pil.board.rcc.sysclk_hz == 64_000_000        # HSI/2 x16
    assert pil.board.systick.r[1] == 64_000_000 // 1000 - 1
    assert pil.read_bits("clock_fault") == [True]
    n = len(pil.ticks)
    pil.run_for(1.0)
    assert len(pil.ticks) - n in (99, 100, 101)         # the tick keeps 10 ms on HSI


def test_outputs_safe_until_sensors_valid(elf):
    pil = Pil(None, elf)
    pil.adc_valid_from = UNITS_PER_S // 2               # no ADC scan completes for 0.5 s
    pil.board.adc_valid = False
    low = [700, 2300, 2300, 600]                        # platform far below the band, plausible pressures
    pil.board.adc_counts[:] = low
    while pil.t_s < 0.45:
        pil.run_for(0.01)
        assert pil.board.gpio_odr("b") & OUT_MASK == 0, f"an output on at {pil.t_s:.2f} s without sensors"
    assert pil.read_bits("outputs_safe") == [True] and pil.read_bits("sensors_valid") == [False]
    pil.run_for(1.5)
    assert pil.read_bits("sensors_valid") == [True]
    # Sensors missing at boot latch a sensor fault: outputs stay safe until an
    # operator clears it (coil clear_faults); then the controller acts.
    assert pil.read_bits("fault_latched") == [True] and pil.board.gpio_odr("b") & OUT_MASK == 0
    pil.write_coil("clear_faults", True)
    pil.run_for(1.0)
    assert pil.board.gpio_odr("b") >> 12 & 1, "compressor not started for a platform below the band"


def test_watchdog_quiet_in_a_normal_run(elf):
    pil = boot(elf)
    pil.run_for(2.0)
    assert len(pil.boots) == 1
    assert pil.board.iwdg.running and pil.board.iwdg.refreshes >= 190
    assert pil.read_bits("watchdog_reset") == [False]


def band(pil):
    hi1, lo1, hi2, lo2 = pil.read_registers("holding", register_address("holding", "band_lower_um"), 4)
    return hi1 << 16 | lo1, hi2 << 16 | lo2


def words(lower_um, upper_um):
    return [lower_um >> 16, lower_um & 0xFFFF, upper_um >> 16, upper_um & 0xFFFF]


def test_settings_survive_a_reset(elf):
    pil = boot(elf)
    lower, upper = band(pil)
    new = (lower + 5000, upper + 5000)
    pil.write_registers(register_address("holding", "band_lower_um"), words(*new))
    pil.run_for(1.5)                                    # saved 1 s after the last change
    assert pil.board.flash_if.programs > 0 and not pil.board.anomalies
    pil.boot(POWER_ON_FLAGS)
    pil.wait_first_tick()
    assert band(pil) == new


def test_watchdog_resets_a_stalled_main_loop(elf):
    pil = boot(elf)
    lower, upper = band(pil)
    pil.board.flash_if.stuck_busy = True                # the next flash operation never ends
    pil.write_registers(register_address("holding", "band_lower_um"), words(lower + 1000, upper))
    t_write = pil.t_s
    pil.run_for(2.0)
    assert [f for _, f in pil.boots] == [POWER_ON_FLAGS, IWDG_RESET_FLAGS]
    t_reset = pil.boots[1][0]
    # saved 1 s after the write, then the IWDG: 375 x 32 / 40 kHz = 300 ms
    assert 1.0 + 0.2 < t_reset - t_write < 1.0 + 0.1 + 0.4
    assert pil.ticks[-1].t_s > t_reset                  # the rebooted image runs its loop again
    assert pil.read_bits("watchdog_reset") == [True]
    assert band(pil) == (lower, upper)                  # the stalled save never landed

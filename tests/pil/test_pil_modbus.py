"""Modbus RTU against the emulated image, with pymodbus's serial (RTU)
client as the master on USART1's byte stream: measurements, a band change the platform follows,
exception 03 for an invalid write."""

import time
from pathlib import Path

from pymodbus.client import ModbusSerialClient

from leveler_pil.serial_bridge import SerialBridge
from leveler_pil.run import Pil, register_address



def i32(hi, lo):
    v = hi << 16 | lo
    return v - (1 << 32) if v & 0x8000_0000 else v


def words(v):
    v &= 0xFFFF_FFFF
    return [v >> 16, v & 0xFFFF]


def test_master_reads_changes_band_and_is_refused(elf):
    pil = Pil(Path(__file__).parent / "configs/steady-900lb.ini", elf)
    pil.commission()
    pil.start_plant()
    band_addr = register_address("holding", "band_lower_um")
    height_addr = register_address("input", "height_um")
    with SerialBridge(pil) as bridge:
        client = ModbusSerialClient(port=bridge.url, baudrate=19200, parity="E", stopbits=1, bytesize=8,
                                    timeout=2, retries=3)
        assert client.connect()
        try:
            r = client.read_input_registers(height_addr, count=2, device_id=1)
            assert not r.isError(), r
            height_um = i32(*r.registers)
            assert abs(height_um - pil.plant.state()[1] * 1e6) < 2000    # what the plant holds, within ~1 count

            b = client.read_holding_registers(band_addr, count=4, device_id=1).registers
            lower, upper = i32(*b[:2]), i32(*b[2:])
            new_lower, new_upper = lower + 4_000, upper + 4_000
            w = client.write_registers(band_addr, words(new_lower) + words(new_upper), device_id=1)
            assert not w.isError(), w
            deadline = time.monotonic() + 120
            while True:
                h = i32(*client.read_input_registers(height_addr, count=2, device_id=1).registers)
                if new_lower <= h <= new_upper:
                    break
                assert time.monotonic() < deadline, f"platform at {h} um, band {new_lower}..{new_upper}"
                time.sleep(0.5)
            assert new_lower / 1e6 <= pil.plant.state()[1] <= new_upper / 1e6 + 1e-4

            bad = client.write_registers(band_addr, words(new_upper) + words(new_lower), device_id=1)
            assert bad.isError() and bad.exception_code == 3
            again = client.read_holding_registers(band_addr, count=4, device_id=1).registers
            assert [i32(*again[:2]), i32(*again[2:])] == [new_lower, new_upper]
        finally:
            client.close()

#!/usr/bin/env python3
"""Writes firmware/fuzz/corpus/: one small file per path through modbus_rtu.c
and the PDU server it frames (modbus_pdu.c).

Each file is an ADU without its CRC (address, function code, data); the
harness (rtu_harness.c) runs it raw, with its CRC appended, with a small
response buffer (last byte % 12) and twice as a byte stream through
leveler_modbus_rtu_poll(). Addresses are those of firmware/regmap/registers.json.
Run it again after changing the list; the fuzzer adds its finds elsewhere.
"""
import os
import struct
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
OUT = os.path.join(HERE, "corpus")


def pdu(fc, *words, raw=b""):
    return bytes([fc]) + b"".join(struct.pack(">H", w) for w in words) + raw


def adu(address, body):
    return bytes([address]) + body


def multi_regs(start, values, byte_count=None):
    data = b"".join(struct.pack(">H", v) for v in values)
    bc = len(data) if byte_count is None else byte_count
    return pdu(0x10, start, len(values), raw=bytes([bc]) + data)


def i32(v):
    u = v & 0xFFFFFFFF
    return [u >> 16, u & 0xFFFF]


CASES = {
    # reads, FC 01-04
    "fc01_ok": adu(1, pdu(0x01, 0, 5)),
    "fc01_short": adu(1, pdu(0x01, 0) + b"\x00"),
    "fc01_qty0": adu(1, pdu(0x01, 0, 0)),
    "fc01_qty2001": adu(1, pdu(0x01, 0, 2001)),
    "fc01_addr": adu(1, pdu(0x01, 4, 2)),
    "fc02_ok": adu(1, pdu(0x02, 0, 8)),
    "fc02_cap4": adu(1, pdu(0x02, 0, 4)),
    "fc03_ok": adu(1, pdu(0x03, 0, 25)),
    "fc03_holes": adu(1, pdu(0x03, 20, 16)),
    "fc03_short": adu(1, pdu(0x03, 0, 1) + b"\x00"),
    "fc03_qty0": adu(1, pdu(0x03, 0, 0)),
    "fc03_qty126": adu(1, pdu(0x03, 0, 126)),
    "fc03_addr": adu(1, pdu(0x03, 0xFFFF, 1)),
    "fc03_split": adu(1, pdu(0x03, 3, 1)),
    "fc03_cap7": adu(1, pdu(0x03, 0, 7)),
    "fc04_ok": adu(1, pdu(0x04, 0, 33)),
    "fc04_split": adu(1, pdu(0x04, 1, 1)),
    # single writes, FC 05-06
    "fc05_on": adu(1, pdu(0x05, 1, 0xFF00)),
    "fc05_off": adu(1, pdu(0x05, 1, 0x0000)),
    "fc05_badvalue": adu(1, pdu(0x05, 1, 0x1234)),
    "fc05_short": adu(1, pdu(0x05, 1)),
    "fc05_addr": adu(1, pdu(0x05, 5, 0xFF00)),
    "fc05_clear": adu(1, pdu(0x05, 0, 0xFF00)),
    "fc06_ok": adu(1, pdu(0x06, 14, 25)),
    "fc06_cap1": adu(1, pdu(0x06, 14, 0x0301)),
    "fc06_refused_enum": adu(1, pdu(0x06, 0, 7)),
    "fc06_split": adu(1, pdu(0x06, 2, 0)),
    "fc06_hole": adu(1, pdu(0x06, 26, 0)),
    "fc06_addr": adu(1, pdu(0x06, 56, 0)),
    "fc06_long": adu(1, pdu(0x06, 14, 25, 0)),
    "fc06_baud_fast": adu(1, pdu(0x06, 24, 1152)),
    "fc06_baud_slow": adu(1, pdu(0x06, 24, 12)),
    "fc06_new_address": adu(1, pdu(0x06, 23, 5)),
    # multiple writes, FC 15-16
    "fc15_ok": adu(1, pdu(0x0F, 1, 4, raw=b"\x01\x0D")),
    "fc15_qty0": adu(1, pdu(0x0F, 1, 0, raw=b"\x00")),
    "fc15_qty1969": adu(1, pdu(0x0F, 0, 1969, raw=b"\xf7")),
    "fc15_bytecount": adu(1, pdu(0x0F, 1, 4, raw=b"\x02\x0D\x00")),
    "fc15_len": adu(1, pdu(0x0F, 1, 4, raw=b"\x01\x0D\x00")),
    "fc15_short": adu(1, pdu(0x0F, 1, 4)),
    "fc15_addr": adu(1, pdu(0x0F, 3, 4, raw=b"\x01\x0F")),
    "fc15_cap2": adu(1, pdu(0x0F, 1, 2, raw=b"\x01\x02")),
    "fc16_band_ok": adu(1, multi_regs(2, i32(390000) + i32(410000))),
    "fc16_band_refused": adu(1, multi_regs(2, i32(400000) + i32(400000))),
    "fc16_qty0": adu(1, pdu(0x10, 0, 0, raw=b"\x00")),
    "fc16_qty124": adu(1, pdu(0x10, 0, 124, raw=b"\xf8")),
    "fc16_bytecount": adu(1, multi_regs(0, [1], byte_count=4)),
    "fc16_len": adu(1, multi_regs(0, [1]) + b"\x00"),
    "fc16_short": adu(1, pdu(0x10, 0, 1)),
    "fc16_addr": adu(1, multi_regs(55, [0, 0])),
    "fc16_cap3": adu(1, multi_regs(12, [120, 0x0103])),
    # addressing
    "broadcast_write": adu(0, pdu(0x06, 14, 32)),
    "broadcast_write_cap0": adu(0, pdu(0x05, 1, 0xFF00)),
    "broadcast_read": adu(0, pdu(0x03, 0, 1)),
    "broadcast_read_coils": adu(0, pdu(0x01, 0, 1)),
    "broadcast_bad_function": adu(0, pdu(0x2B, 0x0E01)),
    "other_address": adu(7, pdu(0x03, 0, 1)),
    "reserved_address_faulty_hal": adu(0xF8, pdu(0x03, 0, 10)),
    # functions not served, tiny and oversized frames
    "fc07": adu(1, bytes([0x07])),
    "fc2b": adu(1, pdu(0x2B, 0x0E01, raw=b"\x00")),
    "fc83": adu(1, pdu(0x83, 0, 1)),
    "empty": b"",
    "one_byte": b"\x01",
    "two_bytes": b"\x01\x03",
    "oversized": adu(1, multi_regs(0, [0] * 140, byte_count=255)),
    "oversized_faulty_hal": adu(0x81, bytes(299)),
}


def main():
    os.makedirs(OUT, exist_ok=True)
    for old in os.listdir(OUT):
        os.remove(os.path.join(OUT, old))
    for name, data in CASES.items():
        with open(os.path.join(OUT, name), "wb") as f:
            f.write(data)
    print(f"{len(CASES)} files in {OUT}", file=sys.stderr)


if __name__ == "__main__":
    main()

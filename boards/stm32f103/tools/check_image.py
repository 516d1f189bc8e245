#!/usr/bin/env python3
"""Size and float-helper check of the STM32F103 image (stdlib only).

Flash used = every allocated section placed in flash (0x0800_0000..) plus the
.data initialisers stored there; static RAM = sections in SRAM (0x2000_0000..),
i.e. .data + .bss. Fails (exit 1) when over budget or when any soft-float
helper (__aeabi_f*/__aeabi_d*, or libgcc's __*sf*/__*df* routines) is linked.
Exit 77 (the CTest skip code) when --skip-if-missing and the ELF does not exist.
"""
import argparse
import os
import re
import subprocess
import sys

FLASH_BASE, FLASH_END = 0x08000000, 0x08100000
RAM_BASE, RAM_END = 0x20000000, 0x20100000
FLOAT_HELPER = re.compile(
    r"^(__aeabi_[fd]\w*|__(add|sub|mul|div|neg|cmp|eq|ne|lt|le|gt|ge|unord)[sd]f[23]"
    r"|__(fix|fixuns)[sd]f\w+|__float\w*[sd]f|__extendsfdf2|__truncdfsf2)$")


def run(tool, *args):
    try:
        return subprocess.run([tool, *args], check=True, capture_output=True, text=True).stdout
    except (OSError, subprocess.CalledProcessError) as err:
        sys.exit(f"check_image: {tool} {' '.join(args)} failed: {err}")


def measure(size_tool, elf):
    flash = ram = 0
    data_bytes = 0
    for line in run(size_tool, "-A", "-d", elf).splitlines():
        fields = line.split()
        if len(fields) != 3 or not fields[1].isdigit() or not fields[2].isdigit():
            continue
        name, size, addr = fields[0], int(fields[1]), int(fields[2])
        if FLASH_BASE <= addr < FLASH_END:
            flash += size
        elif RAM_BASE <= addr < RAM_END:
            ram += size
            if name == ".data":
                data_bytes = size
    return flash + data_bytes, ram  # .data initialisers also live in flash


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("elf")
    ap.add_argument("--size", default="arm-none-eabi-size")
    ap.add_argument("--nm", default="arm-none-eabi-nm")
    ap.add_argument("--flash-budget", type=int, default=32 * 1024)
    ap.add_argument("--ram-budget", type=int, default=6 * 1024)
    ap.add_argument("--skip-if-missing", action="store_true")
    a = ap.parse_args()

    if not os.path.exists(a.elf):
        if a.skip_if_missing:
            print(f"SKIP: {a.elf} does not exist; run `make firmware` first")
            return 77
        sys.exit(f"check_image: {a.elf}: no such file")

    flash, ram = measure(a.size, a.elf)
    floats = sorted({s.split()[-1] for s in run(a.nm, a.elf).splitlines()
                     if s.split() and FLOAT_HELPER.match(s.split()[-1])})
    name = os.path.basename(a.elf)
    print(f"{name} flash: {flash} of {a.flash_budget} bytes ({100.0 * flash / a.flash_budget:.1f} %)")
    print(f"{name} static RAM (.data+.bss): {ram} of {a.ram_budget} bytes "
          f"({100.0 * ram / a.ram_budget:.1f} %)")
    failed = False
    if flash > a.flash_budget:
        print(f"{a.elf}: flash {flash} bytes exceeds the {a.flash_budget} byte budget", file=sys.stderr)
        failed = True
    if ram > a.ram_budget:
        print(f"{a.elf}: static RAM {ram} bytes exceeds the {a.ram_budget} byte budget", file=sys.stderr)
        failed = True
    if floats:
        print(f"{a.elf}: floating-point helpers linked: {', '.join(floats)}", file=sys.stderr)
        failed = True
    if not failed:
        print(f"{name}: within budget, no floating-point helpers")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())

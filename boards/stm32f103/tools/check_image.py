#!/usr/bin/env python3
"""The STM32F103 image's one budget report and float-helper check (stdlib only).

Counted as the linker counts its regions (ld --print-memory-usage), so the two
never disagree: flash used = from the start of flash to the end of the last
section loaded there (.isr_vector, .text, .ARM.exidx, the .data initialisers,
alignment gaps included); static RAM = from the start of SRAM to the end of
the last section placed there (.data + .bss). Both are set against the
product's budgets, and the chip's regions (from the linker script) are shown
beside them. Fails (exit 1) when over budget or when any soft-float helper
(__aeabi_f*/__aeabi_d*, or libgcc's __*sf*/__*df* routines) is linked.
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


def measure(objdump_tool, elf):
    """(flash bytes, RAM bytes) as region extents, from objdump's section headers."""
    flash_end, ram_end = FLASH_BASE, RAM_BASE
    lines = run(objdump_tool, "-h", "-w", elf).splitlines()
    for line in lines:
        f = line.split()
        if len(f) < 7 or not f[0].isdigit():
            continue
        size, vma, lma, flags = int(f[2], 16), int(f[3], 16), int(f[4], 16), " ".join(f[7:])
        if size == 0 or "ALLOC" not in flags:
            continue
        if "LOAD" in flags and FLASH_BASE <= lma < FLASH_END:   # stored in flash (code, or .data's initialisers)
            flash_end = max(flash_end, lma + size)
        if RAM_BASE <= vma < RAM_END:
            ram_end = max(ram_end, vma + size)
    return flash_end - FLASH_BASE, ram_end - RAM_BASE


REGION = re.compile(r"^\s*(\w+)\s*\([^)]*\)\s*:\s*ORIGIN\s*=\s*(0x[0-9a-fA-F]+|\d+)\s*,\s*LENGTH\s*=\s*(\d+)\s*([KM]?)",
                    re.M)


def regions(linker_script):
    """{name: length in bytes} of the linker script's MEMORY regions."""
    with open(linker_script, encoding="utf-8") as fh:
        text = fh.read()
    return {m[1]: int(m[3]) * {"": 1, "K": 1024, "M": 1024 * 1024}[m[4]] for m in REGION.finditer(text)}


def report(name, flash, ram, a, chip):
    def line(what, used, budget, region):
        where = f"; the chip's {region} region: {chip[region]} B, {100.0 * used / chip[region]:.1f} %" \
            if region in chip else ""
        return f"  {what:<10}{used:>6} of {budget:>6} B budget ({100.0 * used / budget:.1f} %){where}"
    print(f"{name} budget report (the product's budgets; boards/stm32f103/README.md):")
    print(line("flash", flash, a.flash_budget, "FLASH"))
    print(line("static RAM", ram, a.ram_budget, "RAM"))


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("elf")
    ap.add_argument("--objdump", default="arm-none-eabi-objdump")
    ap.add_argument("--size", help=argparse.SUPPRESS)   # older callers; objdump is used
    ap.add_argument("--linker-script", help="show the chip's regions beside the budgets")
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

    flash, ram = measure(a.objdump, a.elf)
    floats = sorted({s.split()[-1] for s in run(a.nm, a.elf).splitlines()
                     if s.split() and FLOAT_HELPER.match(s.split()[-1])})
    name = os.path.basename(a.elf)
    report(name, flash, ram, a, regions(a.linker_script) if a.linker_script else {})
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
        print(f"  within budget, no floating-point helpers")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())

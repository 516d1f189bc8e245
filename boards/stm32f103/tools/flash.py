#!/usr/bin/env python3
"""make flash: write the image to the board through an ST-Link (stdlib only).

Tries OpenOCD (interface/stlink.cfg + target/stm32f1x.cfg: program, verify,
reset), then st-flash (leveler.bin at 0x08000000). When neither reaches a
probe it says which probe it looked for, what each tool answered and how to
attach one. Exit codes: 0 flashed, 1 no probe answered or writing failed,
2 bad input (no image, no tool installed).
"""
import argparse
import glob
import os
import subprocess
import sys

# ST-Link USB ids (vendor 0483, STMicroelectronics), as OpenOCD's interface/stlink.cfg lists them.
STLINK_IDS = {"3744": "ST-LINK/V1", "3748": "ST-LINK/V2", "374b": "ST-LINK/V2-1", "374a": "ST-LINK/V2-1",
              "3752": "ST-LINK/V2-1", "374d": "STLINK-V3", "374e": "STLINK-V3", "374f": "STLINK-V3",
              "3753": "STLINK-V3", "3754": "STLINK-V3"}
FLASH_ADDRESS = "0x08000000"
ATTACH = """how to attach one:
  1. wire the ST-Link to the Blue Pill's 4-pin SWD header: SWDIO-DIO, SWCLK-CLK, GND-GND, 3.3V-3.3
     (power the board from the ST-Link or from USB, not both at 3.3 V);
  2. plug the ST-Link into this computer: `lsusb` should list 0483:3748 (ST-LINK/V2);
  3. let your user open it: the udev rules of Debian's openocd or stlink-tools package
     (/lib/udev/rules.d/60-openocd.rules, 49-stlinkv2.rules), then unplug and plug it again;
  4. run `make flash` again. A board that does not answer: hold RESET while it starts."""


def usb_probes(sysfs="/sys/bus/usb/devices"):
    """ST-Links on USB as 'name (0483:pid)', or None when sysfs cannot be read."""
    if not os.path.isdir(sysfs):
        return None
    found = []
    for dev in sorted(glob.glob(os.path.join(sysfs, "*"))):
        try:
            with open(os.path.join(dev, "idVendor")) as v, open(os.path.join(dev, "idProduct")) as p:
                vid, pid = v.read().strip().lower(), p.read().strip().lower()
        except OSError:
            continue
        if vid == "0483" and pid in STLINK_IDS:
            found.append(f"{STLINK_IDS[pid]} (0483:{pid})")
    return found


def attempt(argv, timeout_s=120):
    """(ok, the tool's last error lines)."""
    try:
        p = subprocess.run(argv, capture_output=True, text=True, timeout=timeout_s)
    except (OSError, subprocess.TimeoutExpired) as e:
        return False, str(e)
    text = (p.stdout + p.stderr).strip().splitlines()
    errors = [l.strip() for l in text if any(w in l.lower() for w in ("error", "warn", "couldn't", "failed"))]
    # st-flash 1.7 exits 0 and only warns when it finds no ST-Link
    ok = p.returncode == 0 and not any("couldn't find any st-link" in e.lower() for e in errors)
    return ok, "; ".join(errors[-3:] or text[-2:]) or f"exit status {p.returncode}"


def main(argv=None):
    ap = argparse.ArgumentParser(prog="make flash", description=__doc__.splitlines()[0],
                                 epilog="exit codes: 0 flashed, 1 no probe answered or writing failed, 2 bad input")
    ap.add_argument("--elf", required=True, help="the image for OpenOCD (program, verify, reset)")
    ap.add_argument("--bin", required=True, help="the raw image for st-flash, written at " + FLASH_ADDRESS)
    ap.add_argument("--openocd", default="", help="OpenOCD's path (empty: not installed)")
    ap.add_argument("--st-flash", default="", help="st-flash's path (empty: not installed)")
    ap.add_argument("--sysfs", default="/sys/bus/usb/devices", help=argparse.SUPPRESS)   # tests
    a = ap.parse_args(argv)
    for path in (a.elf, a.bin):
        if not os.path.isfile(path):
            print(f"make flash: {path}: no such image; run `make firmware`", file=sys.stderr)
            return 2
    if not a.openocd and not a.st_flash:
        print("make flash: neither openocd nor st-flash is installed (scripts/bootstrap installs both: "
              "apt-get install openocd stlink-tools)", file=sys.stderr)
        return 2
    probes = usb_probes(a.sysfs)
    print("make flash: ST-Link on USB: " + ("cannot tell (no /sys/bus/usb here)" if probes is None else
                                          ", ".join(probes) or "none found"))
    tried = []
    if a.openocd:
        print(f"make flash: OpenOCD, ST-Link, program {a.elf} verify reset")
        ok, why = attempt([a.openocd, "-f", "interface/stlink.cfg", "-f", "target/stm32f1x.cfg",
                           "-c", f"program {a.elf} verify reset exit"])
        if ok:
            print("make flash: written and verified with OpenOCD; the board restarted")
            return 0
        tried.append(f"OpenOCD (interface/stlink.cfg, target/stm32f1x.cfg): {why}")
        if a.st_flash:
            print("make flash: OpenOCD did not flash the board; trying st-flash")
    if a.st_flash:
        ok, why = attempt([a.st_flash, "--reset", "write", a.bin, FLASH_ADDRESS])
        if ok:
            print(f"make flash: written with st-flash at {FLASH_ADDRESS}; the board restarted")
            return 0
        tried.append(f"st-flash ({a.bin} at {FLASH_ADDRESS}): {why}")
    print("make flash: the board was not flashed.\n"
          "looked for: an ST-Link (ST-LINK/V2, V2-1 or STLINK-V3; USB 0483:3748, 0483:374b, 0483:374f, ...) "
          "with an STM32F103 behind it on SWD\n"
          "tried:\n  " + "\n  ".join(tried) + "\n" + ATTACH, file=sys.stderr)
    return 1


if __name__ == "__main__":
    sys.exit(main())

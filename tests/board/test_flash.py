"""Issue 22: `make flash` as a user meets it, without a probe (there is none on
the test machine): the real OpenOCD and st-flash are tried and the message
names the probe looked for and how to attach it; with stand-in tools, the
fall-back from OpenOCD to st-flash and the exact st-flash command."""
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
FLASH = ROOT / "boards" / "stm32f103" / "tools" / "flash.py"


def image(tmp):
    elf, bin_ = tmp / "leveler.elf", tmp / "leveler.bin"
    elf.write_bytes(b"\x7fELF" + bytes(60))
    bin_.write_bytes(bytes(256))
    return elf, bin_


def flash(*args):
    return subprocess.run([sys.executable, str(FLASH), *map(str, args)], capture_output=True, text=True,
                          timeout=300)


def tool(tmp, name, body):
    path = tmp / name
    path.write_text("#!/bin/sh\n" + body)
    path.chmod(0o755)
    return path


@pytest.mark.skipif(not (shutil.which("openocd") and shutil.which("st-flash")), reason="openocd/st-flash absent")
def test_no_probe_with_the_real_tools_says_what_it_looked_for(tmp_path):
    elf, bin_ = image(tmp_path)
    p = flash("--elf", elf, "--bin", bin_, "--openocd", shutil.which("openocd"),
              "--st-flash", shutil.which("st-flash"), "--sysfs", tmp_path / "no-usb")
    assert p.returncode == 1, p.stdout + p.stderr
    assert "trying st-flash" in p.stdout                       # OpenOCD first, then the fall-back
    err = p.stderr
    assert "looked for: an ST-Link" in err and "0483:3748" in err
    assert "OpenOCD (interface/stlink.cfg" in err and "open failed" in err      # OpenOCD's own words
    assert "st-flash (" in err and "Couldn't find any ST-Link" in err           # st-flash's own words
    assert "SWDIO" in err and "SWCLK" in err and "udev" in err


def test_falls_back_to_st_flash_and_writes_the_bin_at_the_flash_base(tmp_path):
    elf, bin_ = image(tmp_path)
    log = tmp_path / "st-flash.args"
    openocd = tool(tmp_path, "openocd", "echo 'Error: open failed' >&2\nexit 1\n")
    st_flash = tool(tmp_path, "st-flash", f"echo \"$@\" > {log}\necho 'Flash written and verified! jolly good!'\n")
    p = flash("--elf", elf, "--bin", bin_, "--openocd", openocd, "--st-flash", st_flash)
    assert p.returncode == 0, p.stderr
    assert "written with st-flash at 0x08000000" in p.stdout
    assert log.read_text().split() == ["--reset", "write", str(bin_), "0x08000000"]


def test_openocd_success_stops_there(tmp_path):
    elf, bin_ = image(tmp_path)
    log = tmp_path / "openocd.args"
    openocd = tool(tmp_path, "openocd", f"printf '%s\\n' \"$@\" > {log}\n")
    st_flash = tool(tmp_path, "st-flash", "exit 99\n")
    p = flash("--elf", elf, "--bin", bin_, "--openocd", openocd, "--st-flash", st_flash)
    assert p.returncode == 0 and "verified with OpenOCD" in p.stdout
    assert log.read_text().splitlines() == ["-f", "interface/stlink.cfg", "-f", "target/stm32f1x.cfg", "-c",
                                            f"program {elf} verify reset exit"]


def test_probe_seen_on_usb_is_named(tmp_path):
    elf, bin_ = image(tmp_path)
    dev = tmp_path / "usb" / "1-1"
    dev.mkdir(parents=True)
    (dev / "idVendor").write_text("0483\n")
    (dev / "idProduct").write_text("3748\n")
    st_flash = tool(tmp_path, "st-flash", "echo 'WARN usb.c: Couldn'\"'\"'t find any ST-Link devices' >&2\n")
    p = flash("--elf", elf, "--bin", bin_, "--st-flash", st_flash, "--sysfs", tmp_path / "usb")
    assert "ST-Link on USB: ST-LINK/V2 (0483:3748)" in p.stdout
    assert p.returncode == 1      # st-flash 1.7 exits 0 when it finds no probe: still not flashed


def test_no_tool_or_no_image_is_bad_input(tmp_path):
    elf, bin_ = image(tmp_path)
    p = flash("--elf", elf, "--bin", bin_)
    assert p.returncode == 2 and "neither openocd nor st-flash is installed" in p.stderr
    p = flash("--elf", tmp_path / "none.elf", "--bin", bin_, "--st-flash", "/bin/true")
    assert p.returncode == 2 and "none.elf" in p.stderr and "make firmware" in p.stderr

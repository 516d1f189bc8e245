"""Issue 22: one budget report for the board image, counted as the linker
counts its regions: the flash figure is the size of leveler.bin (objcopy's
image from 0x08000000 to the last loaded byte), measured independently."""
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
BUILD = Path(os.environ.get("LEVELER_BOARD_BUILD", ROOT / "build" / "stm32f103"))


def test_flash_figure_is_the_image_size_and_regions_come_from_the_linker_script():
    elf, bin_ = BUILD / "leveler.elf", BUILD / "leveler.bin"
    if not elf.exists() or not bin_.exists():
        pytest.skip("no board image; run make firmware")
    p = subprocess.run([sys.executable, str(ROOT / "boards" / "stm32f103" / "tools" / "check_image.py"), str(elf),
                        "--linker-script", str(ROOT / "boards" / "stm32f103" / "stm32f103c8.ld")],
                       capture_output=True, text=True, check=True)
    flash = re.search(r"^\s+flash\s+(\d+) of\s+32768 B budget \(([\d.]+) %\); the chip's FLASH region: (\d+) B",
                      p.stdout, re.M)
    assert flash, p.stdout
    assert int(flash[1]) == bin_.stat().st_size
    assert float(flash[2]) == round(100.0 * bin_.stat().st_size / 32768, 1)
    assert int(flash[3]) == 62 * 1024        # stm32f103c8.ld: FLASH LENGTH = 62K (the settings page apart)
    assert re.search(r"^\s+static RAM\s+\d+ of\s+6144 B budget .* RAM region: 20480 B", p.stdout, re.M)

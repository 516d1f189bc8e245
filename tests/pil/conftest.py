"""The PIL tests run the image `make firmware` built; a missing image, Qiling
or plant library is a failure, never a skip."""
import os
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
CONFIGS = ROOT / "host_sim/configs"


@pytest.fixture(scope="session")
def elf():
    path = Path(os.environ.get("LEVELER_ELF", ROOT / "build/stm32f103/leveler.elf"))
    if not path.is_file():
        pytest.fail(f"{path}: no STM32F103 image; `make firmware` builds it (make test does first)")
    try:
        import qiling  # noqa: F401
    except ImportError as e:
        pytest.fail(f"qiling is not installed in this python ({e}); run scripts/bootstrap")
    return path

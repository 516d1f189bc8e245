import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))
import rigproc  # noqa: E402


@pytest.fixture
def plant(tmp_path):
    p = rigproc.Plant(tmp_path)
    yield p
    p.stop()


@pytest.fixture
def thesis_plant(tmp_path):
    p = rigproc.Plant(tmp_path, config=rigproc.PLANT_CONFIG)
    yield p
    p.stop()

import os
import sys

import numpy as np
import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.abspath(os.path.join(HERE, "..", ".."))
sys.path[:0] = [os.path.join(ROOT, "scripts"), HERE]

LB = 4.4482216152605


@pytest.fixture(scope="session")
def cplant():
    """The C plant through ctypes; skipped when the library is not built."""
    from leveler.diagnose import cplant as cp
    from leveler.diagnose.errors import DiagnoseInputError
    try:
        return cp.CPlant()
    except (DiagnoseInputError, OSError) as e:
        pytest.skip(f"libleveler_diag.so not available: {e}")


def thesis_schedule(end=55.0, on=5.0, off=35.0, base_lb=900.0, step_lb=200.0):
    t = np.round(np.arange(0.0, end + 1e-9, 0.01), 2)
    load = np.where((t >= on) & (t < off), (base_lb + step_lb) * LB, base_lb * LB)
    return t, load

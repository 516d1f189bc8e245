"""The project's C plant through libleveler_pil_plant.so (host_sim/pil/pil_plant.c),
stepped by the one firmware-in-the-loop stepper (host_sim/sim/stepper.h) with
the emulated image's outputs as its commands hook. The one place the harness
touches the plant.
The library is looked up in $LEVELER_PIL_PLANT_LIB, then in the installed leveler
package (pip install .: leveler/_lib), then in the build folders.
"""

from __future__ import annotations

import ctypes
import glob
import os
from pathlib import Path

from leveler import paths

ROOT = Path(__file__).resolve().parents[3]
ABI = 3
_u16p = ctypes.POINTER(ctypes.c_uint16)


class PlantError(RuntimeError):
    pass


def find_library():
    env = os.environ.get("LEVELER_PIL_PLANT_LIB")
    if env:
        if not Path(env).is_file():
            raise PlantError(f"LEVELER_PIL_PLANT_LIB={env}: no such file")
        return env
    packaged = paths.packaged("_lib", "libleveler_pil_plant.so")
    if packaged:
        return packaged
    for b in ("build/pil", "build/test", "build/bench", "build/sim", "build/*"):
        hits = sorted(glob.glob(str(ROOT / b / "host_sim/pil/libleveler_pil_plant.so")))
        if hits:
            return hits[0]
    raise PlantError("libleveler_pil_plant.so not found: `make pil` builds it (or set LEVELER_PIL_PLANT_LIB)")


class Plant:
    """One plant per process (the library keeps it in static storage)."""

    def __init__(self, config, lib=None):
        self.lib = ctypes.CDLL(lib or find_library())
        if self.lib.pil_abi_version() != ABI:
            raise PlantError(f"{lib}: ABI {self.lib.pil_abi_version()}, harness needs {ABI}")
        self.lib.pil_end_s.restype = ctypes.c_double
        err = ctypes.create_string_buffer(512)
        self.config = str(config)
        self.algorithm = self.lib.pil_open(self.config.encode(), err, len(err))
        if self.algorithm < 0:
            raise PlantError(err.value.decode())
        self.end_s = self.lib.pil_end_s()

    def sensor_counts(self, noisy=True):
        """Height, P2, P1, P3 as 12-bit counts; noisy: one draw of the config's
        seeded noise (as leveler-sim draws one per tick), else noise-free."""
        c = (ctypes.c_uint16 * 4)()
        self.lib.pil_sensor_counts(int(noisy), c)
        return list(c)

    def state(self):
        """(t_s, height_m, p_spring_pa, p_pipe_pa, p_acc_pa, load_n)."""
        s = (ctypes.c_double * 6)()
        self.lib.pil_state(s)
        return tuple(s)

    def step(self, outputs):
        """One tick through the stepper (host_sim/sim/stepper.h): the image's
        actuators (compressor, spring, vent, acc; the config's [initial] ones at
        the first tick) and the scheduled load, then 10 ms of RK4. Returns the
        state at the tick's start with its load, and the actuators applied."""
        applied = (ctypes.c_int32 * 4)()
        self.lib.pil_decide((ctypes.c_int32 * 4)(*[int(bool(o)) for o in outputs]), applied)
        st = self.state()
        self.lib.pil_advance()
        return st, tuple(bool(v) for v in applied)

    def commission_registers(self, algorithm=0):
        """[(address, [values...]), ...]: the holding registers a commissioning
        engineer writes for this config, in runs a master writes with FC 16."""
        runs = (ctypes.c_uint16 * 64)()
        values = (ctypes.c_uint16 * 4096)()
        err = ctypes.create_string_buffer(512)
        n = self.lib.pil_commission_registers(algorithm, runs, 32, values, 4096, err, len(err))
        if n < 0:
            raise PlantError(err.value.decode())
        return [(runs[2 * k], list(values[runs[2 * k]:runs[2 * k] + runs[2 * k + 1]])) for k in range(n)]

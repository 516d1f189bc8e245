"""The project's C plant for the harness: the engine's stepping API (leveler.engine,
host_sim/diagnose/engine.h: engine_step_*), stepped by the one firmware-in-the-loop
stepper (host_sim/sim/stepper.h) with the emulated image's outputs as its commands
hook. The one place the harness touches the plant. The engine is found as every
Python caller finds it ($LEVELER_DIAG_LIB, the installed package, the build folders).
"""

from __future__ import annotations

from leveler import engine
from leveler.errors import InputError


class PlantError(RuntimeError):
    pass


class Plant:
    """A config's plant at its initial state at t = 0, stepped one tick at a time."""

    def __init__(self, config, lib=None):
        self.config = str(config)
        try:
            self._e = engine.Engine(self.config, lib=lib)
            self.algorithm = self._e.step_open()
        except (engine.EngineError, InputError) as e:
            raise PlantError(str(e)) from None
        self.end_s = self._e.end_s

    def sensor_counts(self, noisy=True):
        """Height, P2, P1, P3 as 12-bit counts; noisy: one draw of the config's
        seeded noise (as leveler-sim draws one per tick), else noise-free."""
        return self._e.step_counts(noisy)

    def state(self):
        """(t_s, height_m, p_spring_pa, p_pipe_pa, p_acc_pa, load_n)."""
        return self._e.step_state()

    def step(self, outputs):
        """One tick through the stepper (host_sim/sim/stepper.h): the image's
        actuators (compressor, spring, vent, acc; the config's [initial] ones at
        the first tick) and the scheduled load, then 10 ms of RK4. Returns the
        state at the tick's start with its load, and the actuators applied."""
        return self._e.step(outputs)

    def commission_registers(self, algorithm=0):
        """[(address, [values...]), ...]: the holding registers a commissioning
        engineer writes for this config, in runs a master writes with FC 16."""
        try:
            return self._e.commission_registers(algorithm)
        except engine.EngineError as e:
            raise PlantError(str(e)) from None

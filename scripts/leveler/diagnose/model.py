"""The one interface the diagnosis uses to reach a plant.

    simulate(config, run, effect, params, mode) -> Trace

`run` supplies the time base, the load schedule (load_n) and, in replay mode,
the logged actuator commands (driven open loop, so controller timing does not
hide plant errors). In closed-loop mode the firmware runs in the loop.
The simulation is always the project's C plant (cplant.py); tests may pass a
stand-in through a "module:factory" spec.
"""
import importlib
from dataclasses import dataclass

import numpy as np

REPLAY = "replay"
CLOSED_LOOP = "closed_loop"


@dataclass
class Trace:
    t_s: np.ndarray
    signals: dict        # height_m, p_spring_pa, p_pipe_pa, p_acc_pa (as a sensor would read them)
    commands: dict       # compressor, spring_valve, vent_valve, acc_valve as driven


class Simulator:
    """Base class: a plant that can be simulated for a run."""

    # whether simulate() starts a run where its start_shift moves it (the C plant
    # does); a simulator that does not is scored from the logged start only
    honours_start_shift = False

    def configs(self):
        """Names of the plant configs this simulator knows."""
        raise NotImplementedError

    def simulate(self, config, run, effect, params, mode):
        """effect: name or None; params: dict name -> value (missing = nominal)."""
        raise NotImplementedError

    def generate(self, config, t_s, load_n, truth_effect, truth_params, seed):
        """Closed-loop run with a truth-generator variant switched on (blind test)."""
        raise NotImplementedError


DEFAULT_SPEC = "leveler.diagnose.cplant:CPlant"


def make_simulator(spec=None):
    """Instantiate 'module:factory' (default: the C plant through ctypes)."""
    spec = spec or DEFAULT_SPEC
    mod, _, fn = spec.partition(":")
    return getattr(importlib.import_module(mod), fn)()

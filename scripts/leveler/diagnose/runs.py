"""Run logs (docs/log-format.md) as the diagnosis sees them.

Reading and checking is leveler.runlog's (file:line: field messages, unit
sniffing, increasing time); this module adds the checks the diagnosis needs
(enough samples, a measured height and spring pressure) and keeps the arrays
in the shape the pipeline uses.
"""
import os
from dataclasses import dataclass, field

import numpy as np

from leveler import runlog

from .errors import DiagnoseInputError

COMMANDS = runlog.ACTUATORS     # the trace's commands: the log's actuators
SIGNALS = runlog.SIGNALS
MIN_ROWS = 50


@dataclass
class Run:
    """One run: signals sampled at t_s (SI). Missing signal = all-NaN array."""
    path: str
    t_s: np.ndarray
    signals: dict                      # name -> array (NaN where not measured)
    load_n: np.ndarray
    commands: dict = field(default_factory=dict)   # name -> int array; only fully logged ones
    config: str = ""
    source: str = ""
    # a planned run's register writes [(t_s, {register: value})] (schedule files' mode and
    # manual columns, docs/config-format.md); closed loop only, none in a log
    writes: list = field(default_factory=list)
    # the start the simulation takes moved by (height m, P2 Pa): what the log's
    # quiet start cannot resolve (fit.Problem's start_shifts, design's knife edge)
    start_shift: tuple = (0.0, 0.0)
    # a coarse log's commands on the 10 ms replay grid, each switch placed within
    # the samples that bracket it (CPlant.placed, edges.py); None: halfway
    fine_commands: dict = None

    @property
    def name(self):
        return os.path.basename(self.path)

    @property
    def has_commands(self):
        return all(c in self.commands for c in ("compressor", "spring_valve", "vent_valve"))

    def measured(self, signal):
        a = self.signals.get(signal)
        return a is not None and bool(np.isfinite(a).mean() > 0.5)


def sample_interval(runs):
    """The finest of the runs' median sample intervals (s): the shortest time the logs
    resolve (0 when no run has two samples)."""
    out = [float(np.median(np.diff(r.t_s))) for r in runs if len(r.t_s) > 1]
    return min(out) if out else 0.0


def load_run(path):
    """Read and check one run log. Raises DiagnoseInputError naming file:line: field."""
    try:
        log = runlog.read(path)
    except runlog.RunLogError as e:
        raise DiagnoseInputError(str(e)) from None
    n = len(log.t_s)
    if n < MIN_ROWS:
        raise DiagnoseInputError(f"{path}: only {n} data rows; a diagnosis needs at least {MIN_ROWS}")
    if not np.isfinite(log.p_spring_pa).mean() > 0.5:
        raise DiagnoseInputError(f"{path}: column p_spring_pa: mostly empty; the diagnosis needs "
                                 f"the spring pressure P2")
    commands = {c: getattr(log, c).astype(np.int32) for c in COMMANDS
                if np.isfinite(getattr(log, c)).all()}
    return Run(path=str(path), t_s=log.t_s, signals={s: getattr(log, s) for s in SIGNALS},
               load_n=log.load_n, commands=commands, config=log.config, source=log.source)


def write_run(path, t_s, signals, load_n, commands=None, config="", source="sim"):
    """Write a run log (the blind test's "real" logs)."""
    commands = commands or {}
    log = runlog.RunLog.from_arrays(t_s, signals["height_m"], load_n,
                                    p_spring_pa=signals.get("p_spring_pa"),
                                    p_pipe_pa=signals.get("p_pipe_pa"),
                                    p_acc_pa=signals.get("p_acc_pa"),
                                    config=config, source=source,
                                    **{c: commands.get(c) for c in COMMANDS})
    runlog.write(path, log)

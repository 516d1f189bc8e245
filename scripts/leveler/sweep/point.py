"""One point of a sweep: its INI written, resolved by the C loader (the config
hash), run with leveler-sim (found as leveler.config finds it:
$LEVELER_SIM, the installed package, the checkout's build folders) and
measured (leveler.sweep.figures). ``run`` is what a Dask worker executes; it
touches nothing but a temporary folder of its own, so a task run twice (a
worker lost, a retry) has no effect outside the result it returns.
"""
from __future__ import annotations

import os
import subprocess
import tempfile
import time

from .. import config as config_mod
from .. import runlog
from . import figures, study


class SimulationFailed(RuntimeError):
    """leveler-sim failed on a config the loader accepted (the task is retried)."""


def _command(point, ini, log):
    cmd = [config_mod.find_sim(), "--config", ini, "--log", log, "--quiet"]
    if point.algorithm is not None:
        cmd += ["--algorithm", str(point.algorithm)]
    if point.schedule:
        cmd += ["--schedule", point.schedule]
    if point.end_s is not None:
        cmd += ["--end-s", repr(point.end_s)]
    return cmd


def _row(point, names):
    row = {"point": point.index, "point_id": point.point_id, "config": point.config,
           "scenario": point.scenario, "algorithm": point.algorithm}
    row.update(point.settings)
    row.update({"config_hash": None, "version": None, "error": None})
    row.update(dict.fromkeys(names))
    return row


def run(point, names=figures.NAMES):
    """{"row": the table row, "wall_s": time taken, "simulated_s": the run's length}.
    A config the loader refuses gives a row with its message in "error"."""
    start = time.perf_counter()
    row, simulated = _row(point, names), 0.0
    with tempfile.TemporaryDirectory(prefix="leveler-sweep-") as tmp:
        ini, log_path = os.path.join(tmp, f"{point.point_id}.ini"), os.path.join(tmp, "run.csv")
        with open(ini, "w", encoding="utf-8") as fh:
            fh.write(point.ini_text())
        try:
            cfg = config_mod.load(ini)
        except config_mod.ConfigError as e:
            row["error"] = str(e).replace(ini, f"point {point.point_id}")
            return {"row": row, "wall_s": time.perf_counter() - start, "simulated_s": 0.0}
        row["config_hash"] = study.resolved_hash(cfg.values)[:16]
        p = subprocess.run(_command(point, ini, log_path), capture_output=True, text=True)
        if p.returncode == 2:
            row["error"] = p.stderr.strip().replace(ini, f"point {point.point_id}")
        elif p.returncode != 0:
            raise SimulationFailed(f"point {point.point_id}: leveler-sim exit {p.returncode}: {p.stderr.strip()}")
        else:
            log = runlog.read(log_path)
            row["version"] = log.meta.get("version")
            row.update(figures.measure(log, cfg.band_lower_m, cfg.band_upper_m, names))
            simulated = float(log.t_s[-1])
    return {"row": row, "wall_s": time.perf_counter() - start, "simulated_s": simulated}

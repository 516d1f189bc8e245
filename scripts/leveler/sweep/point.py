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
    """{"row": the table row, "wall_s": time taken, "simulated_s": the run's length,
    "stages_s": where the time went (resolve, simulate, read, measure)}.
    A config the loader refuses gives a row with its message in "error"."""
    clock = [time.perf_counter()]
    stages, simulated, row = {}, 0.0, _row(point, names)

    def lap(stage):
        clock.append(time.perf_counter())
        stages[stage] = clock[-1] - clock[-2]
    with tempfile.TemporaryDirectory(prefix="leveler-sweep-") as tmp:
        ini, log_path = os.path.join(tmp, "point.ini"), os.path.join(tmp, "run.csv")
        with open(ini, "w", encoding="utf-8") as fh:
            fh.write(point.ini_text())
        try:
            cfg = config_mod.load(ini)
        except config_mod.ConfigError as e:
            row["error"] = str(e).replace(ini, "point.ini")
            cfg = None
        lap("resolve")
        if cfg is not None:
            row["config_hash"] = study.resolved_hash(cfg.values)[:16]
            p = subprocess.run(_command(point, ini, log_path), capture_output=True, text=True)
            lap("simulate")
            if p.returncode == 2:
                row["error"] = p.stderr.strip().replace(ini, "point.ini")
            elif p.returncode != 0:
                raise SimulationFailed(f"point {point.point_id}: leveler-sim exit {p.returncode}: {p.stderr.strip()}")
            else:
                log = runlog.read(log_path)
                lap("read")
                row["version"] = log.meta.get("version")
                row.update(figures.measure(log, cfg.band_lower_m, cfg.band_upper_m, names))
                simulated = float(log.t_s[-1])
                lap("measure")
    return {"row": row, "wall_s": time.perf_counter() - clock[0], "simulated_s": simulated, "stages_s": stages}


def run_many(points, names=figures.NAMES):
    """Several points in one task (leveler-sweep --batch): their results in order."""
    return [run(p, names) for p in points]

"""Runs a sweep's points: on dask.distributed, or serially in this process.

Dask does the distribution: one future per point (its key is the point's id,
so a point is never submitted twice), ``retries=`` for a task that raised
(leveler-sim crashed), the scheduler's own rescheduling when a worker dies
(a task on a lost worker runs again elsewhere; a task that kills workers
``distributed.scheduler.allowed-failures`` times is given up as KilledWorker).
Results come back to this process in the order they finish; only this process
writes the table (leveler.sweep.table), so a task run twice cannot write a
row twice.

``--scheduler ADDRESS`` runs on an existing cluster: its workers need the same
leveler (installed, or the checkout on the same path) and leveler-sim, and
the study's base configs and schedules at the same paths.
"""
from __future__ import annotations

import contextlib
import dataclasses
import logging
import os
import sys
import time

from . import point as point_mod


@dataclasses.dataclass
class Stats:
    """What a sweep took: for the summary line and make bench."""
    done: int = 0
    failed: int = 0
    wall_s: float = 0.0          # the sweep, submit to last result
    task_wall_s: float = 0.0     # summed over the tasks (each on one core)
    simulated_s: float = 0.0     # summed simulated time
    cores: int = 1
    stages_s: dict = dataclasses.field(default_factory=dict)   # summed per stage (point.run)


class Progress:
    """One line on stderr: done/total, rate, time left (redrawn on a terminal,
    about every 10 % otherwise)."""

    def __init__(self, total, quiet=False, stream=sys.stderr, prog="leveler-sweep", unit="points"):
        self.total, self.quiet, self.stream, self.prog, self.unit = total, quiet, stream, prog, unit
        self.done, self.start, self.last = 0, time.monotonic(), -1
        self.tty = stream.isatty()

    def step(self, n=1):
        self.done += n
        if self.quiet or self.total == 0:
            return
        tenth = 10 * self.done // self.total
        if not self.tty and tenth == self.last and self.done != self.total:
            return
        self.last = tenth
        elapsed = time.monotonic() - self.start
        rate = self.done / elapsed if elapsed > 0 else 0.0
        left = (self.total - self.done) / rate if rate > 0 else float("nan")
        line = f"{self.prog}: {self.done}/{self.total} {self.unit}, {rate:.2f} {self.unit}/s, {left:.0f} s left"
        self.stream.write(("\r" + line + " " * 4) if self.tty else line + "\n")
        if self.tty and self.done == self.total:
            self.stream.write("\n")
        self.stream.flush()


def _account(stats, result):
    stats.done += 1
    stats.task_wall_s += result["wall_s"]
    stats.simulated_s += result["simulated_s"]
    for stage, seconds in result.get("stages_s", {}).items():
        stats.stages_s[stage] = stats.stages_s.get(stage, 0.0) + seconds


def run_serial(points, names, on_row, progress):
    """Every point in this process, in order (the reference a Dask run must equal)."""
    stats, start = Stats(), time.monotonic()
    for p in points:
        result = point_mod.run(p, names)
        _account(stats, result)
        on_row(result["row"])
        progress.step()
    stats.wall_s = time.monotonic() - start
    return stats, []


@contextlib.contextmanager
def client(scheduler=None, workers=None, dashboard=":8787"):
    """A dask.distributed Client: on ``scheduler`` if given, else on a
    LocalCluster of ``workers`` single-threaded worker processes (default:
    one per core)."""
    from dask.distributed import Client, LocalCluster
    if scheduler:
        with Client(scheduler) as c:
            yield c
        return
    n = workers or os.cpu_count() or 1
    with LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=dashboard,
                      silence_logs=logging.CRITICAL) as cluster, Client(cluster) as c:
        yield c


def cores(c):
    """Threads over the cluster's workers (each task uses one core)."""
    return sum(w.get("nthreads", 1) for w in c.scheduler_info()["workers"].values()) or 1


def run_dask(c, points, names, on_rows, progress, retries=2, batch=1):
    """The points as Dask futures, ``batch`` points per task; the rows handed to
    ``on_rows(*rows)`` as they finish (those that finished together in one call:
    one synced table write). Returns (stats, failures): failures are (point,
    exception) after the retries."""
    from dask.distributed import as_completed
    stats, start = Stats(cores=cores(c)), time.monotonic()
    chunks = [tuple(points[i:i + batch]) for i in range(0, len(points), batch)]
    futures = {c.submit(point_mod.run_many, ch, names, key=f"leveler-sweep-{ch[0].point_id}-{len(ch)}",
                        retries=retries): ch for ch in chunks}
    failures = []
    try:
        for done in as_completed(list(futures)).batches():   # every result in hand: one table write
            rows = []
            for fut in done:
                try:
                    results = fut.result()
                except Exception as e:          # after the retries; KilledWorker too
                    failures += [(p, e) for p in futures[fut]]
                    stats.failed += len(futures[fut])
                    results = []
                for result in results:
                    _account(stats, result)
                    rows.append(result["row"])
                progress.step(len(futures[fut]))
                fut.release()
            on_rows(*rows)
    except BaseException:
        c.cancel(list(futures))
        raise
    stats.wall_s = time.monotonic() - start
    return stats, failures

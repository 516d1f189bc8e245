"""Throughput of a sweep (make bench): simulated seconds per wall second per
core, beside leveler-sim's own as a process, and the scaling from 1 to 2 Dask
workers; where a point's time goes. docs/scale.md is computed from these.

    python -m leveler.sweep.bench [--study FILE] [--points N] [--out DIR]

The thesis gives no run time for its own program (Appendix B), so there is
no such column.
"""
from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

from .. import cli as leveler_cli
from .. import runlog
from . import cluster, point as point_mod, study as study_mod, table as table_mod

BATCH = 10     # points per task in the last run


def sim_alone(p, repeats):
    """leveler-sim as the sweep runs it (a process writing the log): median wall per run."""
    walls = []
    with tempfile.TemporaryDirectory(prefix="leveler-sweep-bench-") as tmp:
        ini, log = os.path.join(tmp, "p.ini"), os.path.join(tmp, "run.csv")
        with open(ini, "w", encoding="utf-8") as fh:
            fh.write(p.ini_text())
        cmd = point_mod._command(p, ini, log)
        for _ in range(repeats):
            t0 = time.perf_counter()
            subprocess.run(cmd, check=True, capture_output=True)
            walls.append(time.perf_counter() - t0)
        simulated = float(runlog.read(log).t_s[-1])
    return statistics.median(walls), simulated


def _sweep(points, names, workers, batch=1):
    """One sweep into a fresh table; workers None: serial in this process.
    Returns (stats, cluster start-up s, Dask's cost per task s)."""
    with tempfile.TemporaryDirectory(prefix="leveler-sweep-bench-") as tmp:
        table = table_mod.Table(tmp, [("point", "int"), ("point_id", "str")])
        table.open()
        progress = cluster.Progress(len(points), quiet=True)
        if workers is None:
            return cluster.run_serial(points, names, table.append, progress)[0], 0.0, 0.0
        t0 = time.monotonic()
        with cluster.client(workers=workers, dashboard=":0") as c:
            c.run(lambda: __import__("leveler.sweep.point"))   # imports done before the clock starts
            startup = time.monotonic() - t0
            stats, failures = cluster.run_dask(c, points, names, table.append, progress, batch=batch)
            overhead = task_overhead(c)
        if failures:
            raise RuntimeError(f"{len(failures)} points failed: {failures[0][1]}")
        return stats, startup, overhead


def _nothing(i):
    return i


def task_overhead(c, n=2000):
    """Wall per task of n tasks that do nothing (submitted as the sweep submits
    points, results gathered as they finish): the engine's own cost per task."""
    from dask.distributed import as_completed
    t0 = time.monotonic()
    futures = [c.submit(_nothing, i, key=f"bench-nothing-{i}") for i in range(n)]
    for batch in as_completed(futures).batches():
        for f in batch:
            f.result()
    return (time.monotonic() - t0) / n


def measure(points, names, repeats):
    """Every figure of the bench as a dict (also written as bench.json)."""
    load_before = os.getloadavg()[0]
    sim_wall, simulated = sim_alone(points[0], repeats)
    serial, _, _ = _sweep(points, names, None)
    one, startup1, overhead1 = _sweep(points, names, 1)
    two, startup2, overhead2 = _sweep(points, names, 2)
    two_b, _, _ = _sweep(points, names, 2, BATCH)
    return {"points": len(points), "simulated_s_per_point": simulated,
            "sim_alone_wall_s": sim_wall, "sim_alone_rate": simulated / sim_wall,
            "runs": {name: {"wall_s": s.wall_s, "cores": s.cores, "task_wall_s": s.task_wall_s / s.done,
                            "rate": s.simulated_s / s.wall_s / s.cores,
                            "stages_s": {k: v / s.done for k, v in s.stages_s.items()}}
                     for name, s in (("serial", serial), ("dask-1", one), ("dask-2", two),
                                     (f"dask-2-batch{BATCH}", two_b))},
            "cluster_startup_s": {"dask-1": startup1, "dask-2": startup2},
            "dask_task_overhead_s": {"dask-1": overhead1, "dask-2": overhead2},
            "speedup_1_to_2": one.wall_s / two.wall_s, "cpu_count": os.cpu_count(),
            "load_average_1min": [load_before, os.getloadavg()[0]]}


def report(m):
    runs = m["runs"]
    lines = [f"leveler-sweep bench: {m['points']} points of {m['simulated_s_per_point']:.0f} s simulated each, "
             f"{m['cpu_count']} cores on this machine (1-min load average {m['load_average_1min'][0]:.2f} before, "
             f"{m['load_average_1min'][1]:.2f} after: other work shares the cores)",
             f"leveler-sim alone (a process writing its log): {m['sim_alone_wall_s'] * 1e3:.1f} ms per run, "
             f"{m['sim_alone_rate']:.0f} simulated s per wall s (one core)",
             f"{'sweep':<28} {'points':>6} {'cores':>5} {'wall s':>8} {'s/point':>9} {'sim s/wall s/core':>12}"]
    for name, label in (("serial", "serial, in process"), ("dask-1", "Dask LocalCluster, 1 worker"),
                        ("dask-2", "Dask LocalCluster, 2 workers"), (f"dask-2-batch{BATCH}", f"  the same, --batch {BATCH}")):
        r = runs[name]
        lines.append(f"{label:<28} {m['points']:>6} {r['cores']:>5} {r['wall_s']:>8.2f} {r['task_wall_s']:>9.3f} "
                     f"{r['rate']:>12.0f}")
    st = runs["serial"]["stages_s"]
    lines.append("a point (serial): " + ", ".join(f"{k} {v * 1e3:.1f} ms" for k, v in st.items())
                 + f"; the rest (INI, temp folder, table row) "
                   f"{(runs['serial']['task_wall_s'] - sum(st.values())) * 1e3:.1f} ms")
    lines.append("Dask's own cost per task (2000 tasks that do nothing): "
                 f"{m['dask_task_overhead_s']['dask-1'] * 1e3:.2f} ms (1 worker), "
                 f"{m['dask_task_overhead_s']['dask-2'] * 1e3:.2f} ms (2 workers)")
    lines.append(f"scaling 1 -> 2 workers: {m['speedup_1_to_2']:.2f}x faster "
                 f"({m['speedup_1_to_2'] / 2 * 100:.0f} % of linear); cluster start-up "
                 f"{m['cluster_startup_s']['dask-1']:.1f} s / {m['cluster_startup_s']['dask-2']:.1f} s (not in the walls)")
    return "\n".join(lines)


def main(argv=None):
    ap = leveler_cli.parser("python -m leveler.sweep.bench", __doc__)
    ap.add_argument("--study", default="accumulator",
                    help="the study whose points are timed (a file or a shipped study's name; default accumulator)")
    ap.add_argument("--points", type=int, default=60, help="its first N points (default 60)")
    ap.add_argument("--repeats", type=int, default=20, help="runs of leveler-sim alone (default 20)")
    ap.add_argument("--out", metavar="DIR", help="write bench.json here")
    a = ap.parse_args(argv)
    try:
        s = study_mod.load(study_mod.find(a.study))
    except study_mod.StudyError as e:
        print(f"leveler-sweep bench: error: {e}", file=sys.stderr)
        return leveler_cli.EXIT_BAD_INPUT
    m = measure(s.points()[:a.points], s.figures, a.repeats)
    print(report(m))
    if a.out:
        os.makedirs(a.out, exist_ok=True)
        runlog.write_text_atomic(os.path.join(a.out, "bench.json"), json.dumps(m, indent=2) + "\n")
    return leveler_cli.EXIT_OK


if __name__ == "__main__":
    sys.exit(main())

"""Runs the blind test's cases: on dask.distributed (leveler-sweep's cluster,
leveler.sweep.cluster.client), or one after the other in this process (--serial).

A case (make the logs with a truth, diagnose them as a separate process, run the
proposed experiment) is one Dask task, keyed by this run and the case's index
(its folder's number) so that none is submitted twice; a task that raised or lost its worker runs again once (Dask's
retries and rescheduling). On Dask each diagnosis runs with --jobs 1: the cases
are the parallel work, one core each. Results are reported as they finish and
returned in the cases' order, so the tables do not depend on who finished first.
"""
import os

from . import blindtest as bt

_SIM = None


def _simulator():
    """The truth simulator, one per worker process (a ctypes handle does not travel)."""
    global _SIM
    if _SIM is None:
        _SIM = bt.make_simulator()
    return _SIM


def run_one(job):
    """One case: job = (index, function name in blindtest, args after the simulator, kwargs)."""
    _, fn, args, kw = job
    return getattr(bt, fn)(_simulator(), *args, **kw)


def add_options(ap):
    """The engine's options on leveler-blindtest's parser."""
    ap.add_argument("--serial", action="store_true",
                    help="run the cases one after the other in this process (default: on Dask)")
    ap.add_argument("--scheduler", metavar="ADDRESS", help="an existing Dask scheduler (default: a LocalCluster)")
    ap.add_argument("--workers", type=int, help="LocalCluster worker processes (default: one per core)")
    ap.add_argument("--dashboard", default=":0", help="LocalCluster dashboard address (default: any free port)")


def diagnosis_extra(a, extra, cases):
    """The diagnosis's options: one process each when the cases run side by side.
    A single case runs here, its diagnosis with its own two processes."""
    if cases < 2 and not a.scheduler:
        a.serial = True
    return list(extra) + ([] if a.serial else ["--jobs", "1"])


def run_jobs(jobs, a, on_result, prog="leveler-blindtest"):
    """Runs jobs [(index, fn, args, kwargs)]; on_result(job, result) as each finishes;
    returns the results in the jobs' order."""
    from leveler.sweep import cluster
    results = {}
    if a.serial:
        for job in jobs:
            results[job[0]] = run_one(job)
            on_result(job, results[job[0]])
        return [results[j[0]] for j in jobs]
    from dask.distributed import as_completed
    with cluster.client(a.scheduler, a.workers, a.dashboard) as c:
        print(f"{prog}: {len(jobs)} cases on {cluster.cores(c)} Dask worker threads; dashboard {c.dashboard_link}",
              flush=True)
        futures = {c.submit(run_one, job, key=f"{prog}-{os.getpid()}-{job[0]}", retries=1): job for job in jobs}
        try:
            for fut in as_completed(list(futures)):
                job = futures[fut]
                results[job[0]] = fut.result()      # a case that failed twice stops the run: its error is real
                on_result(job, results[job[0]])
                fut.release()
        except BaseException:
            c.cancel(list(futures))
            raise
    return [results[j[0]] for j in jobs]

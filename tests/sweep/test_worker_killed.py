"""Issue 20: a worker killed mid-sweep (SIGKILL to its process, while it runs
a point): the sweep still completes with every point, none twice, and the
table is the serial run's."""
import logging
import os
import signal

from dask.distributed import Client, LocalCluster

from sweeprun import rows, run, start, wait_rows, write_study

POINTS = 16


def _kill_a_busy_worker(c):
    """SIGKILL to the process of a worker that is running a point now; its pid."""
    for _ in range(500):
        busy = [w for w, keys in c.processing().items() if keys]
        if busy:
            pid = c.run(os.getpid, workers=[busy[0]])[busy[0]]
            os.kill(pid, signal.SIGKILL)
            return pid
    raise AssertionError("no worker was running a point")


def test_a_worker_killed_mid_sweep_every_point_once(tmp_path, monkeypatch):
    # the killed worker cannot remove its point's temporary folder: it goes under tmp_path
    monkeypatch.setenv("TMPDIR", str(tmp_path))
    # 150 s runs: each point takes about 0.2 s, the kill lands mid-sweep
    study = write_study(tmp_path, charges=[100, 120], volumes=[25, 50, 75, 100], end_s=150)
    out = tmp_path / "dask"
    with LocalCluster(n_workers=2, threads_per_worker=1, dashboard_address=":0",
                      silence_logs=logging.CRITICAL) as cluster, Client(cluster) as c:
        proc = start(study, out, "--scheduler", cluster.scheduler_address)
        wait_rows(out, 3, proc)
        before = set(c.scheduler_info()["workers"])
        pid = _kill_a_busy_worker(c)
        rows_at_kill = len(rows(out))
        _, err = proc.communicate(timeout=120)
        assert proc.returncode == 0, err[-3000:]
        after = set(c.scheduler_info()["workers"])
    assert rows_at_kill < POINTS, "the kill came after the sweep"
    assert before != after, f"worker {pid} was not replaced: the kill did not take"
    assert f"{POINTS} points in" in err

    table = rows(out)
    ids = [r["point_id"] for r in table]
    assert len(ids) == POINTS and len(set(ids)) == POINTS
    assert [int(r["point"]) for r in table] == list(range(POINTS))
    run(study, tmp_path / "serial", "--serial")
    assert (out / "sweep.csv").read_bytes() == (tmp_path / "serial" / "sweep.csv").read_bytes()

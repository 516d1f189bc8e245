"""Issue 20: a small sweep on a 2-worker LocalCluster gives the same table as
the same sweep run serially in one process, bit for bit (CSV and Parquet);
so does the same with several points per task (--batch)."""
import pyarrow.parquet as pq

from sweeprun import rows, run, write_study


def test_two_worker_local_cluster_gives_the_serial_table_bit_for_bit(tmp_path):
    study = write_study(tmp_path, charges=[100, 120], volumes=[25, 50, 100])      # 12 points
    serial = run(study, tmp_path / "serial", "--serial")
    dask = run(study, tmp_path / "dask", "--workers", "2", "--dashboard", ":0")
    assert "12 to run" in serial.stderr and "LocalCluster" not in serial.stderr
    assert "Dask LocalCluster, 2 worker threads; dashboard http://" in dask.stderr
    assert "12 ran in" in dask.stderr and "on 2 cores" in dask.stderr

    a, b = (tmp_path / "serial" / "sweep.csv").read_bytes(), (tmp_path / "dask" / "sweep.csv").read_bytes()
    assert a == b
    ta, tb = pq.read_table(tmp_path / "serial" / "sweep.parquet"), pq.read_table(tmp_path / "dask" / "sweep.parquet")
    assert ta.equals(tb, check_metadata=True)
    assert (tmp_path / "serial" / "sweep.parquet").read_bytes() == (tmp_path / "dask" / "sweep.parquet").read_bytes()
    run(study, tmp_path / "batched", "--workers", "2", "--dashboard", ":0", "--batch", "5")   # 3 tasks of 5, 5, 2
    assert (tmp_path / "batched" / "sweep.csv").read_bytes() == a

    table = rows(tmp_path / "dask")
    assert [int(r["point"]) for r in table] == list(range(12))
    assert len({r["point_id"] for r in table}) == 12
    assert all(r["error"] == "" and r["version"] and r["time_return_after_step_s"] for r in table)
    # the table is not twelve copies of one run: the charge changes the return
    assert len({r["time_return_after_step_s"] for r in table}) > 6

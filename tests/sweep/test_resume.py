"""Issue 20: an interrupted sweep started again skips the points it has (and
never writes a point twice): killed (SIGKILL, a half line left at the end of
the table) or interrupted (SIGINT, exit 130), then run again."""
import signal

from sweeprun import rows, run, start, wait_rows, write_study

POINTS = 16


def _interrupt(study, out, sig, n):
    proc = start(study, out, "--serial")
    wait_rows(out, n, proc)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=60)
    return proc.returncode, err


def test_killed_sweep_resumed_skips_the_done_points(tmp_path):
    study = write_study(tmp_path, charges=[100, 120], volumes=[25, 50, 75, 100], end_s=150)
    out = tmp_path / "out"
    code, _ = _interrupt(study, out, signal.SIGKILL, 5)
    assert code == -signal.SIGKILL
    done = {r["point_id"]: r for r in rows(out)}
    assert 5 <= len(done) < POINTS
    with open(out / "sweep.csv", "ab") as fh:      # a crash in the middle of a line
        fh.write(b"15,0123456789abcdef,thesis-900lb-t")

    p = run(study, out, "--serial")
    todo = POINTS - len(done)
    assert f"{len(done)} already in" in p.stderr and f"{todo} to run" in p.stderr
    assert f"{todo} ran in" in p.stderr
    table = rows(out)
    ids = [r["point_id"] for r in table]
    assert len(ids) == POINTS and len(set(ids)) == POINTS and "0123456789abcdef" not in ids
    assert all(done[r["point_id"]] == r for r in table if r["point_id"] in done)

    run(study, tmp_path / "ref", "--serial")
    assert (out / "sweep.csv").read_bytes() == (tmp_path / "ref" / "sweep.csv").read_bytes()

    again = run(study, out, "--serial")          # nothing left: nothing runs, nothing changes
    assert f"{POINTS} already in" in again.stderr and "0 to run" in again.stderr
    assert (out / "sweep.csv").read_bytes() == (tmp_path / "ref" / "sweep.csv").read_bytes()


def test_ctrl_c_writes_the_table_and_exits_130(tmp_path):
    study = write_study(tmp_path, charges=[100, 120], volumes=[25, 50, 75], end_s=150)   # 12 points
    out = tmp_path / "out"
    code, err = _interrupt(study, out, signal.SIGINT, 3)
    assert code == 130, err[-2000:]
    assert "interrupted" in err and "the same command continues" in err
    n = len(rows(out))
    assert 3 <= n < 12 and (out / "sweep.parquet").exists()
    p = run(study, out, "--serial")
    assert f"{n} already in" in p.stderr and len({r["point_id"] for r in rows(out)}) == 12

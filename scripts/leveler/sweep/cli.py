"""leveler-sweep: a design study over config keys, on Dask (docs/sweep.md).

  leveler-sweep --study host_sim/studies/accumulator.toml --out build/sweep/accumulator
  leveler-sweep --study STUDY --out DIR --scheduler tcp://HOST:8786
  leveler-sweep --study STUDY --out DIR --serial

Runs every point of the study (an INI that includes the base config and sets
the varied keys, simulated by leveler-sim, measured), and writes DIR/sweep.csv
(as points finish: run the same command again after an interruption and the
points already there are skipped), DIR/sweep.parquet, and heat maps or lines.
"""
from __future__ import annotations

import os
import sys
import tempfile

from .. import cli as leveler_cli
from .. import config as config_mod
from . import cluster, plots, study as study_mod, table as table_mod

EXIT_INTERRUPTED = 130
_OURS = (table_mod.CSV_NAME, table_mod.PARQUET_NAME)


def parse_args(argv):
    ap = leveler_cli.parser("leveler-sweep", __doc__, exit_extra="130 interrupted (run it again to continue)")
    ap.add_argument("--study", required=True, metavar="FILE",
                    help="the study (TOML, docs/sweep.md), or the name of a shipped one: accumulator, "
                         "accumulator-diaphragm, appendix-a (host_sim/studies)")
    ap.add_argument("--out", required=True, metavar="DIR",
                    help="output folder: new, or an earlier output of this study (its points are skipped)")
    where = ap.add_mutually_exclusive_group()
    where.add_argument("--scheduler", metavar="ADDRESS", help="an existing Dask scheduler (tcp://host:8786)")
    where.add_argument("--workers", type=int, metavar="N",
                       help="worker processes of the local cluster (default: one per core)")
    where.add_argument("--serial", action="store_true", help="no cluster: every point in this process, in order")
    ap.add_argument("--retries", type=int, default=2, metavar="N",
                    help="times Dask runs a failed point again (default 2)")
    ap.add_argument("--batch", type=int, default=1, metavar="N",
                    help="points per Dask task (default 1; more for very many short points: docs/scale.md)")
    ap.add_argument("--dashboard", default=":8787", metavar="ADDRESS",
                    help="the local cluster's dashboard address (default :8787; :0 any free port)")
    ap.add_argument("--no-plots", action="store_true", help="the table only")
    ap.add_argument("--quiet", action="store_true", help="no progress line")
    a = ap.parse_args(argv)
    if a.workers is not None and a.workers < 1:
        ap.error("--workers: at least 1")
    if a.batch < 1:
        ap.error("--batch: at least 1")
    return a


def check_out(out):
    if os.path.lexists(out) and not os.path.isdir(out):
        raise study_mod.StudyError(f"--out {out}: exists and is not a folder")
    if os.path.isdir(out):
        foreign = sorted(n for n in os.listdir(out) if n not in _OURS and not n.endswith(".png")
                         and not n.startswith(".sweep."))
        if foreign:
            raise study_mod.StudyError(f"--out {out}: holds files leveler-sweep did not write ({foreign[0]}, ...)")


def check_first(points):
    """The first point's config through the C loader, before any cluster starts
    (a misspelt key fails here, once, not in every task)."""
    with tempfile.TemporaryDirectory(prefix="leveler-sweep-") as tmp:
        ini = os.path.join(tmp, "first-point.ini")
        with open(ini, "w", encoding="utf-8") as fh:
            fh.write(points[0].ini_text())
        try:
            config_mod.load(ini)
        except config_mod.ConfigError as e:
            raise study_mod.StudyError(f"the study's first point: {e}".replace(ini, "(generated INI)")) from None


def prepare(a, say):
    """(study, points to run, table) with the table opened and the done points skipped."""
    study = study_mod.load(study_mod.find(a.study))
    config_mod.find_sim()
    points = study.points()
    check_out(a.out)
    check_first(points)
    table = table_mod.Table(a.out, table_mod.columns(study), study.name)
    done = table.open()
    ids = {p.point_id for p in points}
    stale = done - ids
    for pid in stale:
        del table.rows[pid]
    todo = [p for p in points if p.point_id not in done]
    say(f"leveler-sweep: study '{study.name}': {len(points)} points, {len(points) - len(todo)} already in "
        f"{table.csv_path}, {len(todo)} to run" + (f" ({len(stale)} rows of other points dropped)" if stale else ""))
    return study, todo, table


def execute(a, study, todo, table, say):
    """Runs the points; returns (stats, failures)."""
    progress = cluster.Progress(len(todo), quiet=a.quiet)
    if a.serial or not todo:
        return cluster.run_serial(todo, study.figures, table.append, progress)
    with cluster.client(a.scheduler, a.workers, a.dashboard) as c:
        say(f"leveler-sweep: Dask {'cluster ' + a.scheduler if a.scheduler else 'LocalCluster'}, "
            f"{cluster.cores(c)} worker threads; dashboard {c.dashboard_link}")
        return cluster.run_dask(c, todo, study.figures, table.append, progress, a.retries, a.batch)


def report(a, study, table, stats, failures, say):
    n = table.finish()
    say(f"leveler-sweep: {n} points in {table.csv_path} and {table.parquet_path}")
    if stats.done:
        say(f"leveler-sweep: {stats.done} ran in {stats.wall_s:.1f} s on {stats.cores} cores: "
            f"{stats.task_wall_s / stats.done:.3f} s per point, "
            f"{stats.simulated_s / stats.wall_s / stats.cores:.0f} simulated s per wall s per core")
    if not a.no_plots:
        pngs = plots.plot_all(study, table.sorted_rows(), a.out)
        say("leveler-sweep: " + (", ".join(pngs) if pngs else "no plot: the study varies no key"))
    errors = [r for r in table.rows.values() if r.get("error")]
    for r in errors[:3]:
        print(f"leveler-sweep: point {r['point_id']}: {r['error']}", file=sys.stderr)
    for p, e in failures[:3]:
        print(f"leveler-sweep: point {p.point_id} failed: {type(e).__name__}: {e}", file=sys.stderr)
    if failures:
        print(f"leveler-sweep: {len(failures)} points failed (not in the table: run again to retry them)",
              file=sys.stderr)
    return leveler_cli.EXIT_FAILED if failures or errors else leveler_cli.EXIT_OK


def main(argv=None):
    a = parse_args(sys.argv[1:] if argv is None else argv)
    say = (lambda *_: None) if a.quiet else (lambda m: print(m, file=sys.stderr, flush=True))
    try:
        study, todo, table = prepare(a, say)
    except (study_mod.StudyError, config_mod.ConfigError, table_mod.TableError) as e:
        print(f"leveler-sweep: error: {e}", file=sys.stderr)
        return leveler_cli.EXIT_BAD_INPUT
    try:
        stats, failures = execute(a, study, todo, table, say)
    except KeyboardInterrupt:
        table.finish()
        print(f"\nleveler-sweep: interrupted: {len(table.rows)} points in {table.csv_path}; "
              f"the same command continues", file=sys.stderr)
        return EXIT_INTERRUPTED
    return report(a, study, table, stats, failures, say)

"""leveler-diagnose --fleet DIR: the diagnosis of every rig of a plant, one
Dask task per rig (docs/fleet.md).

    leveler-diagnose --fleet DIR --out OUT [--workers N | --scheduler ADDRESS | --serial]
                     [--fast] [--effects A,B] [--mode auto|replay|closed_loop]

DIR holds one folder per rig: its config (exactly one ``*.ini``), its
calibration run logs (``run*.csv``) and its held-out ones (``holdout*.csv``).
Each rig is diagnosed by leveler-diagnose's own entry point (``cli.main``,
one process's worth: ``--jobs 1``), into ``OUT/<rig>/`` (diagnosis.json,
report.html, ...). Then ``OUT/fleet.csv`` (rig, effect, calibrated
parameters, held-out shrink, how sure) and ``OUT/index.html`` linking each
rig's report. The cluster is leveler-sweep's (leveler.sweep.cluster).
"""
from __future__ import annotations

import contextlib
import csv
import dataclasses
import glob
import io
import json
import os
import sys
import time
from typing import List

from leveler import cli as leveler_cli
from leveler import runlog

from .errors import DiagnoseInputError

COLUMNS = ("rig", "effect", "effects", "calibrated", "shrink_pct", "confidence", "why", "seconds", "report", "error")


@dataclasses.dataclass(frozen=True)
class Rig:
    name: str
    config: str
    runs: List[str]
    holdouts: List[str]


def find_rigs(top):
    """The rigs under ``top``: every folder holding a config and run logs."""
    if not os.path.isdir(top):
        raise DiagnoseInputError(f"--fleet {top}: not a folder")
    rigs = []
    for name in sorted(os.listdir(top)):
        folder = os.path.join(top, name)
        if name.startswith(".") or not os.path.isdir(folder):
            continue
        inis = sorted(glob.glob(os.path.join(folder, "*.ini")))
        runs = sorted(glob.glob(os.path.join(folder, "run*.csv")))
        holdouts = sorted(glob.glob(os.path.join(folder, "holdout*.csv")))
        if len(inis) != 1 or not runs or not holdouts:
            raise DiagnoseInputError(f"--fleet {top}: {name}/ needs one *.ini (has {len(inis)}), run*.csv "
                                     f"(has {len(runs)}) and holdout*.csv (has {len(holdouts)})")
        rigs.append(Rig(name, os.path.abspath(inis[0]), [os.path.abspath(p) for p in runs],
                        [os.path.abspath(p) for p in holdouts]))
    if not rigs:
        raise DiagnoseInputError(f"--fleet {top}: no rig folder in it")
    return rigs


def _calibrated(cal):
    """The calibration's moved parameters as text, as the diagnosis prints them."""
    if not cal:
        return ""
    moved = [p for p in cal.get("parameters", []) if p.get("moved")]
    if not moved:
        return "none"
    if not cal.get("kept"):
        return "not kept" + (f" ({', '.join(p['name'] for p in moved)})" if moved else "")
    return "; ".join(f"{p['name']} {p['change_pct']:+.1f}%" for p in moved)


STAMP = "fleet-inputs.json"   # beside a rig's diagnosis: what it was made from


def inputs_key(rig, extra):
    """What a rig's diagnosis depends on: its resolved config (includes followed,
    by the C loader), its logs' bytes, the options and the leveler version."""
    import hashlib
    import leveler
    from leveler import engine
    h = hashlib.sha256(json.dumps([engine.config_json(rig.config), list(extra), leveler.__version__],
                                  sort_keys=True).encode())
    for path in rig.runs + rig.holdouts:
        h.update(os.path.basename(path).encode())
        with open(path, "rb") as fh:
            h.update(fh.read())
    return h.hexdigest()


def kept_row(rig, out, key):
    """The row of a rig diagnosed before from the same inputs (its stamp and its
    diagnosis.json in place), else None: a fleet run stopped and started again
    does not diagnose a rig twice."""
    try:
        with open(os.path.join(out, STAMP), encoding="utf-8") as fh:
            stamp = json.load(fh)
        if stamp.get("key") != key or not os.path.exists(os.path.join(out, "diagnosis.json")):
            return None
        return _row(rig, out, stamp.get("seconds", ""))
    except (OSError, ValueError, KeyError):
        return None


def diagnose_rig(rig, out, extra, key=None):
    """One rig's diagnosis through leveler-diagnose's entry point (a Dask task):
    its fleet-table row; with key, the stamp that lets a later run keep it."""
    from . import cli
    argv = ["--config", rig.config] + [x for p in rig.runs for x in ("--run", p)]
    argv += [x for p in rig.holdouts for x in ("--holdout", p)] + ["--out", out, "--quiet", "--jobs", "1"]
    with contextlib.suppress(FileNotFoundError):
        os.unlink(os.path.join(out, STAMP))     # stale: this diagnosis replaces what it stood for
    err, start = io.StringIO(), time.perf_counter()
    with contextlib.redirect_stderr(err):
        try:
            code = cli.main(argv + list(extra))
        except SystemExit as e:          # argparse
            code = e.code
    seconds = round(time.perf_counter() - start, 1)
    if code != 0:
        row = dict(dict.fromkeys(COLUMNS, ""), rig=rig.name, seconds=seconds)
        row["error"] = err.getvalue().strip().splitlines()[-1] if err.getvalue().strip() else f"exit {code}"
        return row
    if key:
        runlog.write_text_atomic(os.path.join(out, STAMP), json.dumps({"key": key, "seconds": seconds}))
    return _row(rig, out, seconds)


def _row(rig, out, seconds):
    """A rig's fleet-table row from its diagnosis.json."""
    row = dict(dict.fromkeys(COLUMNS, ""), rig=rig.name, seconds=seconds)
    with open(os.path.join(out, "diagnosis.json"), encoding="utf-8") as fh:
        d = json.load(fh)
    conf = d.get("confidence") or {}
    row.update(effect=d["effect"], effects=" + ".join(d.get("effects", [])), calibrated=_calibrated(d.get("calibration")),
               shrink_pct=round(d["shrink_pct"], 1), confidence=conf.get("level", ""), why=conf.get("why", ""),
               report=f"{rig.name}/report.html")
    return row


def run_rigs(rigs, out, extra, a, say):
    """Every rig's row, in the rigs' order: on Dask (leveler-sweep's cluster), or here."""
    from leveler.sweep import cluster
    rows, jobs = {}, []
    for rig in rigs:
        rig_out, key = os.path.join(out, rig.name), inputs_key(rig, extra)
        kept = None if a.fresh else kept_row(rig, rig_out, key)
        if kept:
            rows[rig.name] = kept
        else:
            jobs.append((rig, rig_out, key))
    if rows:
        say(f"leveler-diagnose --fleet: {len(rows)} rig(s) already diagnosed from the same inputs, kept "
            f"({', '.join(rows)}; --fresh diagnoses them again)")
    progress = cluster.Progress(len(jobs), quiet=a.quiet, prog="leveler-diagnose --fleet", unit="rigs")
    if a.serial or not jobs:
        for rig, rig_out, key in jobs:
            rows[rig.name] = diagnose_rig(rig, rig_out, extra, key)
            progress.step()
        return [rows[rig.name] for rig in rigs]
    from dask.distributed import as_completed
    with cluster.client(a.scheduler, a.workers, a.dashboard) as c:
        say(f"leveler-diagnose --fleet: {len(jobs)} rigs on {cluster.cores(c)} worker threads; "
            f"dashboard {c.dashboard_link}")
        futures = {c.submit(diagnose_rig, rig, rig_out, extra, key, key=f"leveler-fleet-{rig.name}", retries=1):
                   rig.name for rig, rig_out, key in jobs}
        for fut in as_completed(list(futures)):
            try:
                rows[futures[fut]] = fut.result()
            except Exception as e:           # after the retry; a lost worker too
                rows[futures[fut]] = dict(dict.fromkeys(COLUMNS, ""), rig=futures[fut], error=f"{type(e).__name__}: {e}")
            progress.step()
    return [rows[rig.name] for rig in rigs]


_PAGE = """<!doctype html>
<html><head><meta charset="utf-8"><title>leveler fleet diagnosis</title>
<style>body{font-family:sans-serif;margin:2em}table{border-collapse:collapse}
td,th{border:1px solid #ccc;padding:4px 8px;text-align:left}th{background:#eee}.err{color:#b00}</style></head>
<body><h1>Fleet diagnosis: {{ rows|length }} rigs</h1>
<p>leveler {{ version }}, {{ fleet }}. One diagnosis per rig (leveler-diagnose); the table is also in fleet.csv.</p>
<table><tr><th>rig</th><th>effect</th><th>calibrated</th><th>held-out shrink</th><th>how sure</th><th>why</th><th>s</th></tr>
{% for r in rows %}<tr><td>{% if r.report %}<a href="{{ r.report }}">{{ r.rig }}</a>{% else %}{{ r.rig }}{% endif %}</td>
{% if r.error %}<td colspan="6" class="err">failed: {{ r.error }}</td>{% else %}<td>{{ r.effects or r.effect }}</td>
<td>{{ r.calibrated }}</td><td>{{ r.shrink_pct }} %</td><td>{{ r.confidence }}</td><td>{{ r.why }}</td><td>{{ r.seconds }}</td>{% endif %}</tr>
{% endfor %}</table></body></html>
"""


def write_outputs(out, rows, fleet):
    import jinja2
    import leveler
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=COLUMNS, lineterminator="\n")
    w.writeheader()
    w.writerows(rows)
    runlog.write_text_atomic(os.path.join(out, "fleet.csv"), buf.getvalue())
    page = jinja2.Environment(autoescape=True).from_string(_PAGE).render(rows=rows, version=leveler.__version__,
                                                                         fleet=fleet)
    runlog.write_text_atomic(os.path.join(out, "index.html"), page)


def parse_args(argv):
    ap = leveler_cli.parser("leveler-diagnose", __doc__, exit_extra="1 also: a rig whose diagnosis failed")
    ap.add_argument("--fleet", required=True, metavar="DIR", help="one folder per rig: *.ini, run*.csv, holdout*.csv")
    ap.add_argument("--out", required=True, metavar="DIR", help="fleet.csv, index.html and one folder per rig")
    where = ap.add_mutually_exclusive_group()
    where.add_argument("--scheduler", metavar="ADDRESS", help="an existing Dask scheduler")
    where.add_argument("--workers", type=int, metavar="N", help="local cluster worker processes (default: one per core)")
    where.add_argument("--serial", action="store_true", help="no cluster: the rigs one after the other here")
    ap.add_argument("--dashboard", default=":8787", metavar="ADDRESS", help="the local cluster's dashboard address")
    ap.add_argument("--effects", help="comma-separated candidates, passed to each diagnosis")
    ap.add_argument("--mode", choices=("auto", "replay", "closed_loop"), help="passed to each diagnosis")
    ap.add_argument("--fast", action="store_true", help="smaller fitting budget, passed to each diagnosis")
    ap.add_argument("--quiet", action="store_true", help="no progress line")
    ap.add_argument("--fresh", action="store_true",
                    help="diagnose every rig again (default: keep a rig diagnosed before from the same inputs)")
    return ap.parse_args(argv)


def main(argv):
    a = parse_args(argv)
    say = (lambda *_: None) if a.quiet else (lambda m: print(m, file=sys.stderr, flush=True))
    extra = (["--effects", a.effects] if a.effects else []) + (["--mode", a.mode] if a.mode else []) + \
            (["--fast"] if a.fast else [])
    try:
        rigs = find_rigs(a.fleet)
        out = os.path.abspath(a.out)
        os.makedirs(out, exist_ok=True)
    except (DiagnoseInputError, OSError) as e:
        print(f"leveler-diagnose: error: {e}", file=sys.stderr)
        return leveler_cli.EXIT_BAD_INPUT
    rows = run_rigs(rigs, out, extra, a, say)
    write_outputs(out, rows, os.path.abspath(a.fleet))
    for r in rows:
        say(f"{r['rig']}: " + (f"failed: {r['error']}" if r["error"] else
                               f"{r['effects'] or r['effect']}, shrink {r['shrink_pct']} %, {r['confidence']}"))
    failed = [r for r in rows if r["error"]]
    say(f"leveler-diagnose --fleet: {len(rows) - len(failed)} of {len(rows)} rigs diagnosed; "
        f"{os.path.join(out, 'fleet.csv')}, {os.path.join(out, 'index.html')}")
    return leveler_cli.EXIT_FAILED if failed else leveler_cli.EXIT_OK

"""leveler-diagnose: where the sim-to-real gap lies, which unmodelled effect
causes it, and how far it shrinks (docs/diagnosis.md).

  leveler-diagnose --config thesis-900lb --run real1.csv --run real2.csv \\
                   --holdout real3.csv --out DIR
  leveler-diagnose --config thesis-900lb --features thesis-experiment.json --out DIR
"""
import argparse
import os
import shutil
import sys
import tempfile

import leveler
from leveler import cli as leveler_cli

from . import effects as fx
from .errors import DiagnoseInputError


def parse_args(argv):
    ap = leveler_cli.parser("leveler-diagnose", __doc__)
    ap.add_argument("--config", required=True, help="the rig's plant config: a path to an INI file, or a name under host_sim/configs "
                         "(the installed package carries them)")
    ap.add_argument("--run", action="append", default=[], metavar="CSV", help="calibration run log")
    ap.add_argument("--holdout", action="append", default=[], metavar="CSV",
                    help="held-out run log (never used in fitting)")
    ap.add_argument("--features", metavar="JSON", action="append",
                    help="published event figures instead of traces (see docs/diagnosis.md); "
                         "repeat to hold out the later files")
    ap.add_argument("--out", required=True, metavar="DIR",
                    help="output folder: new, empty, or an earlier output of leveler-diagnose (replaced); "
                         "checked before the diagnosis runs")
    ap.add_argument("--mode", choices=("auto", "replay", "closed_loop"), default="auto",
                    help="replay logged commands (auto when the log has them) or firmware in the loop")
    ap.add_argument("--effects", default=",".join(fx.NAMES),
                    help="comma-separated candidates (default: all seven)")
    ap.add_argument("--jobs", type=int, default=None, help="parallel processes (default: 2)")
    ap.add_argument("--fast", action="store_true", help="smaller fitting budget (blind-test CTest)")
    ap.add_argument("--design", metavar="A,B", default=None,
                    help="propose the experiment that best tells candidate A from B (done anyway "
                         "for candidates the logs cannot tell apart); written to DIR/experiment.csv")
    ap.add_argument("--write-config", metavar="FILE", default=None,
                    help="write the rig's model as found (an include of --config, the calibrated values, the "
                         "named effect as [effect.NAME]) for leveler-sim and every program that runs the plant")
    ap.add_argument("--quiet", action="store_true", help="no progress output")
    ap.add_argument("--allow-config-mismatch", action="store_true",
                    help="diagnose logs whose '# config:' names another config than --config's own name "
                         "(default: refuse them); the mismatch goes into diagnosis.json and the verdict")
    ap.add_argument("--fleet", metavar="DIR", help="diagnose every rig of DIR on Dask instead (one folder per rig; "
                                                   "leveler-diagnose --fleet DIR --help)")
    ap.add_argument("--simulator", default=None, help=argparse.SUPPRESS)   # tests: module:factory
    a = ap.parse_args(argv)
    if a.features is None and (not a.run or not a.holdout):
        ap.error("give --run (at least one) and --holdout (at least one), or --features")
    return a


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    if any(x == "--fleet" or x.startswith("--fleet=") for x in argv):
        from .fleet import main as fleet_main      # every rig of a folder, on Dask (fleet.py)
        return fleet_main(argv)
    a = parse_args(argv)
    say = (lambda *_: None) if a.quiet else (lambda m: print(m, file=sys.stderr, flush=True))
    try:
        return run(a, say)
    except DiagnoseInputError as e:
        print(f"leveler-diagnose: error: {e}", file=sys.stderr)
        return 2


OUT_FILES = ("diagnosis.json", "report.html", "experiment.csv", "calibrated.ini")   # all leveler-diagnose writes into --out


def prepare_out(out):
    """Checks --out before any work and returns a private temporary folder
    beside it (proof that the parent is writable). --out must not exist, be
    empty, or hold only what an earlier run wrote: never delete other files."""
    if os.path.lexists(out) and not os.path.isdir(out):
        raise DiagnoseInputError(f"--out {out}: exists and is not a folder")
    if os.path.isdir(out):
        foreign = sorted(set(os.listdir(out)) - set(OUT_FILES))
        if foreign:
            raise DiagnoseInputError(f"--out {out}: folder holds files leveler-diagnose did not write "
                                     f"({', '.join(foreign[:3])}{', ...' if len(foreign) > 3 else ''}); "
                                     f"give a new or empty folder")
    parent = os.path.dirname(out)
    try:
        os.makedirs(parent, exist_ok=True)
        tmp = tempfile.mkdtemp(prefix=".diagnose-", dir=parent)
        os.chmod(tmp, leveler_cli.umask_mode(0o777))   # becomes --out: the folder open() would make, not 0700
        return tmp
    except OSError as e:
        raise DiagnoseInputError(f"--out {out}: cannot write there: {e.strerror}")


def publish_out(tmp, out):
    """tmp -> out; an earlier output's own files go, nothing else (checked again)."""
    if os.path.isdir(out):
        appeared = set(os.listdir(out)) - set(OUT_FILES)
        if appeared:
            raise DiagnoseInputError(f"--out {out}: files appeared during the run: {', '.join(sorted(appeared))}")
        for name in os.listdir(out):
            os.unlink(os.path.join(out, name))
    os.rename(tmp, out)   # onto an empty folder or a free name


def run(a, say):
    out = os.path.abspath(a.out)
    tmp = prepare_out(out)
    try:
        return diagnose_into(a, say, tmp, out)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def config_name(config):
    """A config's own name ([config] name, else its file name), from a path or a
    name under host_sim/configs (cplant.CONFIG_DIR)."""
    from leveler import config as config_mod
    from .cplant import CONFIG_DIR
    path = config if os.path.exists(config) else os.path.join(CONFIG_DIR, config + ".ini")
    try:
        return config_mod.load(path).name
    except Exception:           # a stand-in simulator's configs are names only
        return os.path.splitext(os.path.basename(config))[0]


def config_mismatch(logs, config):
    """The logs whose '# config:' line names another config than --config's own name."""
    name = config_name(config)
    return [{"log": r.path, "logged": r.config, "config": name} for r in logs if r.config and r.config != name]


def diagnose_into(a, say, tmp, out):
    from . import model, pipeline, report, runs
    candidates = [c.strip() for c in a.effects.split(",") if c.strip()]
    for c in candidates:
        if c not in fx.NAMES:
            raise DiagnoseInputError(f"--effects: unknown effect {c!r} (known: {', '.join(fx.NAMES)})")
    pair = None
    if a.design:
        pair = [c.strip() for c in a.design.split(",")]
        if len(pair) != 2 or any(c not in candidates for c in pair):
            raise DiagnoseInputError(f"--design: expected two of the fitted candidates, A,B (got {a.design!r})")
    sim = model.make_simulator(a.simulator)

    def check(config):
        if hasattr(sim, "check_config"):
            sim.check_config(config)          # exists and loads (file:line errors)
        elif config not in sim.configs():
            raise DiagnoseInputError(f"--config: no plant config named {config!r} "
                                     f"(known: {', '.join(sorted(sim.configs())) or 'none'})")
    check(a.config)
    if a.features:
        from . import features
        calib, holdout = features.load_many(a.features, a.config)
        for r in calib + holdout:
            check(r.config_override)
        mode = model.CLOSED_LOOP
    else:
        say(f"reading {len(a.run)} calibration and {len(a.holdout)} held-out run log(s)")
        calib = [runs.load_run(p) for p in a.run]
        holdout = [runs.load_run(p) for p in a.holdout]
        mode = a.mode
        mismatch = config_mismatch(calib + holdout, a.config)
        if mismatch and not a.allow_config_mismatch:
            raise DiagnoseInputError("; ".join(f"{m['log']}: logged config {m['logged']!r} is not --config's "
                                               f"{m['config']!r}" for m in mismatch)
                                     + " (a diagnosis against another rig's config blames its differences on "
                                       "effects: give that rig's config, or --allow-config-mismatch)")
        for m in mismatch:
            say(f"warning: {m['log']}: logged config {m['logged']!r} is not --config's {m['config']!r}")
        for r in calib + holdout:
            if mode == "replay" and not r.has_commands:
                raise DiagnoseInputError(f"{r.path}: --mode replay needs the compressor, spring_valve and "
                                         f"vent_valve columns filled in")
    result, traces = pipeline.diagnose(a.simulator, sim, a.config, calib, holdout, mode, candidates,
                                       a.jobs, say,
                                       {"starts": 8, "max_nfev": 15, "polish": 1} if a.fast else None,
                                       pair)
    result["version"] = leveler.__version__   # the code that made this diagnosis
    if not a.features and mismatch:
        result["config_mismatch"] = mismatch
    report.write_json(os.path.join(tmp, OUT_FILES[0]), result)
    report.write_html(os.path.join(tmp, OUT_FILES[1]), result, traces)
    if (result.get("calibration") or {}).get("ini"):
        with open(os.path.join(tmp, OUT_FILES[3]), "w") as fh:    # the user's config + what moved
            fh.write(f"; leveler-diagnose {leveler.__version__}: the calibrated config (diagnosis.json, "
                     f"calibration)\n" + result["calibration"]["ini"])
    if result.get("experiment"):
        from . import design
        design.write_schedule(os.path.join(tmp, OUT_FILES[2]), result["experiment"])
    publish_out(tmp, out)
    if a.write_config:
        from . import write_config
        write_config.write(a.write_config, result, config_name(a.config), leveler.__version__)
        say(f"wrote {a.write_config}: the model of these logs (leveler-compare --config {a.write_config} LOG "
            f"reproduces the held-out gap {result['gap_after']['normalised']:.4f})")
    if result.get("config_mismatch"):
        say("verdict against logs of another config: " + ", ".join(
            f"{m['logged']} (not {m['config']})" for m in result["config_mismatch"]))
    say("calibrated: " + _calibrated_line(result.get("calibration") or {}, result))
    say(f"effect: {' + '.join(result['effects']) or 'none'}; held-out shrink {result['shrink_pct']:.1f}%; "
        f"{result['seconds']:.1f} s; wrote {out}/diagnosis.json and report.html")
    return 0


def _calibrated_line(cal, result):
    """The closing line's calibration: the values moved (with the effect that explains
    the held-out runs about as well, and the values alike alone), else, the calibration
    set aside, what it would have moved and for which effect."""
    moved = [p for p in cal.get("parameters", []) if p["moved"]]
    rival = cal.get("rival")
    apart = (" (experiment.csv tells them apart)" if "calibration" in
             (result.get("experiment") or {}).get("between", []) else "")
    if moved:
        return (", ".join(f"{p['name']} {p['change_pct']:+.1f}%" for p in moved)
                + (f"; {rival['effect']} alone would explain the held-out runs about as well{apart}" if rival else "")
                + ("; alike alone: " + ", ".join(f"{a['name']} {a['change_pct']:+.1f}%" for a in cal["alike"])
                   if cal.get("alike") else ""))
    if rival:
        return (f"not kept; {', '.join(rival['moved'])} would explain the held-out runs as well as "
                f"{rival['effect']}{apart}")
    return "no parameter moved"

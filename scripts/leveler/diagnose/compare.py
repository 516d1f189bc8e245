"""leveler-compare: a rig's logs against its model, at a glance.

  leveler-compare --config my-rig.ini LOG [LOG ...] [--against OTHER.ini] [--out DIR]

Replays each log through the model (the config with its [effect.NAME]
sections, as every program runs it) the way the diagnosis scores a held-out
run, prints where and how far the model departs (the diagnosis's "where"
figures: phase x signal, bias and RMS, share of the gap) and the pooled
normalised gap; with --against, the same for another config and the shrink
from it. With --out: compare.json and one PNG per log (the log, the model,
and the other config). Exit 0 done, 1 failed, 2 bad input.
"""
import json
import os
import sys

from leveler import __version__, cli as leveler_cli

from . import fit, gap, runs as runs_mod
from .errors import DiagnoseInputError


def parse_args(argv):
    ap = leveler_cli.parser("leveler-compare", __doc__)
    ap.add_argument("--config", required=True, help="the model: an INI path or a name under host_sim/configs")
    ap.add_argument("logs", nargs="+", metavar="LOG", help="run logs (docs/log-format.md)")
    ap.add_argument("--against", metavar="CONFIG", help="another config to compare with (e.g. the one "
                                                        "before leveler-diagnose --write-config)")
    ap.add_argument("--mode", choices=("auto", "replay", "closed_loop"), default="auto",
                    help="replay the logged commands (auto when the log has them) or run the firmware")
    ap.add_argument("--out", metavar="DIR", help="write compare.json and a PNG per log here")
    return ap.parse_args(argv)


def model_gap(sim, config, logs, mode):
    """(traces, pooled gap, where table) of the logs under config, each run from the
    start that fits it best among the logs' unresolvable start shifts, as the
    diagnosis scores held-out runs (fit.Problem.best_start)."""
    from .evidence_runs import where_table
    sim.check_config(config)
    problem = fit.Problem(sim, config, logs, mode, fit.start_shifts(logs))
    traces = [problem.best_start(r, None, {})[0] for r in logs]
    where, _ = where_table(fit.Problem(sim, config, logs, mode), logs)
    return traces, gap.gap_over_runs(logs, traces), where


def _plots(out, logs, traces, other, name):
    from .report import _trace_plot
    import base64
    for i, r in enumerate(logs):
        png = _trace_plot(r, other[i] if other else traces[i], traces[i], name if other else "none")
        path = os.path.join(out, f"{os.path.splitext(os.path.basename(r.path))[0]}.png")
        with open(path, "wb") as fh:
            fh.write(base64.b64decode(png))


def _print(a, result):
    print(f"{a.config}: normalised gap {result['gap']['normalised']:.4f} over {len(a.logs)} log(s)")
    for w in result["where"]["ranked"][:5]:
        print(f"  #{w['rank']} {w['phase']:<10} {w['signal']:<6} bias {w['bias']:+8.2f} {w['unit']:<4} "
              f"RMS {w['rms']:7.2f} {w['unit']:<4} {w['share_pct']:5.1f} % of the gap")
    if a.against:
        print(f"{a.against}: normalised gap {result['against_gap']['normalised']:.4f}; "
              f"shrink {result['shrink_pct']:.1f} %")


def compare(a, sim):
    from .pipeline import placed
    # a coarse log's switches placed within its samples on the config the diagnosis
    # started from (--against, else --config), as the diagnosis places them
    logs = [runs_mod.load_run(p) for p in a.logs]
    sim.check_config(a.against or a.config)
    logs = placed(sim, a.against or a.config, logs, a.mode)
    traces, g, where = model_gap(sim, a.config, logs, a.mode)
    result = {"version": __version__, "config": a.config, "logs": a.logs, "gap": g, "where": where}
    other = None
    if a.against:
        other, g0, _ = model_gap(sim, a.against, logs, a.mode)
        result.update(against=a.against, against_gap=g0, shrink_pct=gap.shrink(g0["normalised"], g["normalised"]))
    if a.out:
        os.makedirs(a.out, exist_ok=True)
        with open(os.path.join(a.out, "compare.json"), "w") as fh:
            json.dump(result, fh, indent=1, default=float)
        _plots(a.out, logs, traces, other, os.path.basename(a.config))
    return result


def main(argv=None):
    a = parse_args(sys.argv[1:] if argv is None else argv)
    try:
        from .cplant import CPlant
        _print(a, compare(a, CPlant()))
        return 0
    except (DiagnoseInputError, OSError) as e:
        print(f"leveler-compare: error: {e}", file=sys.stderr)
        return 2
    except Exception as e:    # a failed simulation: name it, no traceback for the user
        print(f"leveler-compare: failed: {e}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())

"""Command line: event figures of a run log set beside the thesis.

    python -m leveler.report --log run.csv [--summary out.json] [--plot out.png]
                             [--config cfg.ini] [--units thesis|si]
                             [--compare thesis-900lb-sim|...]

Always prints a table of the figures next to the published ones (the case is
picked from the config name and the base load, or given by --compare) with
the difference. --summary writes the flat JSON (SI, null where not defined);
--plot the figure. Output files are written whole or not at all. Exit status
0 on success, 2 on bad input (log, config or arguments), with a message that
names the file and line.
"""

from __future__ import annotations

import json
import sys

from . import config as config_mod
from . import __version__, cli, events, runlog, thesis


def _fmt(v, unit):
    if v is None:
        return "-"
    if unit in ("in",):
        return f"{v:.3f}"
    if unit == "m":
        return f"{v:.5f}"
    if unit == "Pa":
        return f"{v:.0f}"
    if unit == "psia":
        return f"{v:.1f}"
    return f"{v:.2f}"


_LABELS = {
    "height_before_step_m": "height before the step",
    "lowest_height_m": "lowest height after the step",
    "p2_drop_stop_pa": "P2 when the drop stops",
    "time_stuck_bottom_s": "time stuck at the bottom",
    "p2_breakaway_pa": "P2 at break-away",
    "time_return_after_step_s": "time to return into the band",
    "p2_after_climb_pa": "P2 after the climb",
    "highest_height_m": "highest height after removal",
    "p2_jump_pa": "P2 at the jump",
    "time_stuck_top_s": "time stuck at the top",
    "p2_start_down_pa": "P2 when it starts down",
    "time_return_after_removal_s": "time to return into the band",
}


def format_table(summary, published, case, units="thesis"):
    """The comparison table as text."""
    rows = []
    for key in events.SUMMARY_KEYS:
        run = summary.get(key)
        pub = published.get(key) if published else None
        if units == "thesis":
            run_v, unit = thesis.to_thesis_units(key, run)
            pub_v, _ = thesis.to_thesis_units(key, pub)
        else:
            run_v, pub_v, unit = run, pub, thesis.si_unit(key)
        diff = None if run_v is None or pub_v is None else run_v - pub_v
        rows.append((_LABELS[key], unit, _fmt(run_v, unit), _fmt(pub_v, unit),
                     "-" if diff is None else ("+" if diff >= 0 else "") + _fmt(diff, unit)))
    head = ("figure", "unit", "this run", case or "published", "difference")
    if published is None:                 # the run's own figures, no thesis column
        rows = [r[:3] for r in rows]
        head = head[:3]
    ncol = len(head)
    widths = [max(len(r[i]) for r in rows + [head]) for i in range(ncol)]
    lines = ["  ".join(h.ljust(w) if i < 2 else h.rjust(w) for i, (h, w) in enumerate(zip(head, widths)))]
    lines.append("  ".join("-" * w for w in widths))
    for n, r in enumerate(rows):
        if n == 7:
            lines.append("")           # load removal below
        lines.append("  ".join(c.ljust(w) if i < 2 else c.rjust(w)
                               for i, (c, w) in enumerate(zip(r, widths))))
    return "\n".join(lines)


def build_parser():
    p = cli.parser("python -m leveler.report", "Event figures of a leveler run log beside the thesis.")
    p.add_argument("--log", required=True, help="run-log CSV (docs/log-format.md)")
    p.add_argument("--summary", help="write the event figures as JSON here")
    p.add_argument("--plot", help="write the report figure (PNG) here")
    p.add_argument("--config", help="simulator config (INI): band, hysteresis lines, name")
    p.add_argument("--units", choices=("thesis", "si"), default="thesis",
                   help="units of the printed table and the plot (default thesis: in, psia, s)")
    p.add_argument("--compare", choices=sorted(thesis.CASES),
                   help="published case to compare with (default: from config name, base load and accumulator)")
    p.add_argument("--no-thesis", action="store_true",
                   help="no published column: the run is not a thesis case (another schedule or algorithm)")
    return p


def main(argv=None):
    args = build_parser().parse_args(argv)
    try:
        log = runlog.read(args.log)
        cfg = config_mod.load(args.config) if args.config else config_mod.default_config(log.config)
    except (runlog.RunLogError, config_mod.ConfigError) as e:
        print(f"leveler.report: error: {e}", file=sys.stderr)
        return 2

    opts = events.EventOptions(band_lower_m=cfg.band_lower_m, band_upper_m=cfg.band_upper_m)
    analysis = events.analyze(log, opts)
    summary = analysis.summary()

    base_load = cfg.base_load_n if args.config else float(log.load_n[0])
    acc = None
    if args.config:
        a = cfg.values.get("accumulator", {})
        acc = (a.get("type", "none"), a.get("charge_pa", float("nan")))
    case = args.compare or (None if args.no_thesis else
                            thesis.pick_case(log.config or cfg.name, log.source, base_load, acc))
    published = thesis.CASES.get(case) if case else None

    try:
        if args.summary:
            runlog.write_text_atomic(args.summary, json.dumps(summary, indent=2) + "\n")
        if args.plot:
            from . import plot  # matplotlib only when asked
            plot.plot_run(log, args.plot, analysis=analysis, cfg=cfg, units=args.units)
    except OSError as e:
        print(f"leveler.report: error: {e.filename or ''}: {e.strerror}", file=sys.stderr)
        return 2

    print(f"{args.log} (leveler {__version__}; log written by {log.meta.get('version', 'a version before 0.6.0')}): "
          f"config '{log.config}', source {log.source}, {len(log)} rows, "
          f"{log.t_s[0]:.2f}..{log.t_s[-1]:.2f} s; "
          + (f"compared with {case}" if case else "its own event figures (not a published thesis case)"))
    if not analysis.load_events:
        print("no load step found in load_n: no event figures")
    print(format_table(summary, published, case, args.units))
    return 0


if __name__ == "__main__":
    sys.exit(main())

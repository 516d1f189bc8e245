"""python -m leveler_pil case --config FILE [--end-s S] [--log run.csv] [--json out.json]
   python -m leveler_pil bench      (the thesis 900 lb and diaphragm cases, full length, tick cost)

Runs build/stm32f103/leveler.elf under Qiling against the C plant and
compares with leveler-sim. Exit status 1 when the event figures or the
per-tick actuator decisions disagree."""

import sys

from leveler import cli as leveler_cli

from . import case
from .run import ROOT

BENCH_CONFIGS = ("thesis-900lb.ini", "thesis-900lb-diaphragm.ini")


def run_one(config, end_s, log, json_path):
    print(f"PIL: {config} ...", file=sys.stderr, flush=True)
    pil, cmp = case.run_case(config, end_s, log_path=log)
    print(case.report(pil, cmp, config))
    summary = case.tick_summary(pil)
    print("tick cost: worst {worst_instructions} instructions, {worst_cycles} estimated cycles "
          "({with_h} with handlers) of {budget_cycles}; the image's DWT figure (tick_cycles_worst) "
          "{dwt_tick_cycles_worst}".format(with_h=summary["worst_cycles_with_handlers"], **summary))
    if json_path:
        with open(json_path, "w") as f:
            f.write(case.to_json(pil, cmp))
    return cmp.events_agree and cmp.mismatched_ticks == 0


def main(argv=None):
    ap = leveler_cli.parser("python -m leveler_pil", __doc__)
    sub = ap.add_subparsers(dest="cmd", required=True)
    c = sub.add_parser("case", help="one config under the emulator beside leveler-sim")
    c.add_argument("--config", required=True)
    c.add_argument("--end-s", type=float)
    c.add_argument("--log")
    c.add_argument("--json")
    sub.add_parser("bench", help="the full thesis cases and their tick cost")
    a = ap.parse_args(argv)
    if a.cmd == "case":
        return 0 if run_one(a.config, a.end_s, a.log, a.json) else 1
    ok = True
    for name in BENCH_CONFIGS:
        ok &= run_one(str(ROOT / "host_sim/configs" / name), None, None, None)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())

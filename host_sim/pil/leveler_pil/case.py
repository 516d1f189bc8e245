"""A thesis case under the emulator beside the same case in leveler-sim:
event figures within the thesis tolerances, and the actuator decision at
every tick. Logs are read and written through leveler.runlog (column names
come from there, never spelled here)."""

from __future__ import annotations

import json
import math
import os
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

from leveler import events, runlog

from .run import ROOT, Pil

# The thesis tolerances (docs: 0.05 in, 2 psi, 2.5 s), in SI.
TOLERANCE = {"_m": 0.05 * 0.0254, "_pa": 2 * 6894.757293168361, "_s": 2.5}


def tolerance(key):
    return next(v for suffix, v in TOLERANCE.items() if key.endswith(suffix))


def find_leveler_sim():
    env = os.environ.get("LEVELER_SIM")
    if env:
        return env
    for b in ("build/pil", "build/test", "build/sim", "build/bench"):
        p = ROOT / b / "host_sim/sim/leveler-sim"
        if p.is_file():
            return str(p)
    raise FileNotFoundError("leveler-sim not found: `make pil` builds it (or set LEVELER_SIM)")


def trace_log(trace, config):
    cols = list(zip(*trace.state))
    acts = dict(zip(runlog.ACTUATORS, (list(c) for c in zip(*trace.outputs))))
    return runlog.RunLog.from_arrays(trace.t_s, cols[0], cols[4], p_spring_pa=cols[1], p_pipe_pa=cols[2],
                                     p_acc_pa=cols[3], config=Path(config).stem, source="sim",
                                     meta={"controller": "STM32F103 image under Qiling (PIL)"}, **acts)


def sim_log(config, end_s):
    with tempfile.TemporaryDirectory() as d:
        out = Path(d) / "sim.csv"
        subprocess.run([find_leveler_sim(), "--config", str(config), "--log", str(out), "--end-s", str(end_s)],
                       check=True, capture_output=True, text=True)
        return runlog.read(out)


@dataclass
class Comparison:
    rows: int
    mismatched_ticks: int
    first_mismatch_s: float | None
    figures: dict            # key -> (pil, sim, |diff| <= tolerance)

    @property
    def events_agree(self):
        return all(ok for _, _, ok in self.figures.values())


def compare(pil_log, ref_log):
    n = min(len(pil_log), len(ref_log))
    bad = [k for k in range(n)
           if any(pil_log.column(a)[k] != ref_log.column(a)[k] for a in runlog.ACTUATORS
                  if not math.isnan(ref_log.column(a)[k]))]
    a, b = events.summarize(pil_log), events.summarize(ref_log)
    figures = {}
    for key in events.SUMMARY_KEYS:
        if a[key] is None and b[key] is None:
            continue
        ok = a[key] is not None and b[key] is not None and abs(a[key] - b[key]) <= tolerance(key)
        figures[key] = (a[key], b[key], ok)
    return Comparison(n, len(bad), float(pil_log.t_s[bad[0]]) if bad else None, figures)


def run_case(config, end_s=None, elf=None, log_path=None):
    """(pil, comparison): the case under the emulator, compared with leveler-sim."""
    pil = Pil(config, **({"elf": elf} if elf else {}))
    trace = pil.run_case(end_s)
    log = trace_log(trace, config)
    if log_path:
        runlog.write(log_path, log)
    return pil, compare(log, sim_log(config, trace.t_s[-1]))


def tick_summary(pil):
    worst = max(pil.ticks, key=lambda t: t.cycles)
    worst_isr = max(t.cycles_with_isr for t in pil.ticks)
    return {"ticks": len(pil.ticks), "worst_instructions": max(t.instructions for t in pil.ticks),
            "worst_cycles": worst.cycles, "worst_cycles_at_s": round(worst.t_s, 3),
            "worst_cycles_with_handlers": worst_isr, "budget_cycles": 720_000,
            "dwt_tick_cycles_worst": pil.read_u32_register("tick_cycles_worst")}


def report(pil, cmp, config):
    lines = [f"{Path(config).name}: {cmp.rows} ticks, actuators differ from leveler-sim at "
             f"{cmp.mismatched_ticks} ticks" + (f" (first at {cmp.first_mismatch_s:.2f} s)" if cmp.mismatched_ticks else ""),
             f"{'figure':28s} {'PIL':>12s} {'leveler-sim':>12s}  within tolerance"]
    for key, (a, b, ok) in cmp.figures.items():
        fa = "-" if a is None else f"{a:.6g}"
        fb = "-" if b is None else f"{b:.6g}"
        lines.append(f"{key:28s} {fa:>12s} {fb:>12s}  {'yes' if ok else 'NO'}")
    emu = pil.t_s
    lines.append(f"emulated {emu:.1f} s in {pil.wall_s:.1f} s wall: {emu / pil.wall_s:.2f} emulated s per wall s")
    return "\n".join(lines)


def to_json(pil, cmp):
    return json.dumps({"rows": cmp.rows, "mismatched_ticks": cmp.mismatched_ticks,
                       "figures": {k: list(v) for k, v in cmp.figures.items()},
                       "emulated_s": pil.t_s, "wall_s": pil.wall_s, "tick_cost": tick_summary(pil)}, indent=1)

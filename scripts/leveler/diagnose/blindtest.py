"""leveler-blindtest: does the diagnosis name the effect that is really there?

For each case (seven effects and `none`) and seed: the C plant with the
effect's TRUTH variant (a different functional form from the candidate the
diagnosis fits: host_sim/blindtest/truth.c, catalogued in truth.json, built
into libleveler_truth.so, not part of the product) at a random strength
within its physical range runs closed loop with the firmware, on three different load
schedules (two for calibration, one held out); sensor noise is added. The
label is sealed in a file the diagnosis never sees; the diagnosis runs as a
separate process on the logs alone. Then: confusion matrix, hit rate,
held-out shrink of the correctly named cases, false effects in `none` cases.

Targets (docs/diagnosis.md): >= 90 % named right, median shrink >= 70 % when
right, no effect named in a `none` case.
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

from leveler import thesis

from . import cplant
from . import effects as fx
from . import runs
from .model import make_simulator

LB = thesis.N_PER_LBF
CONFIG = "thesis-900lb"
CASES = fx.NAMES + ["none"]
NOISE_HEIGHT_M = 0.08e-3     # LVDT: about one 12-bit count of a 0.25 m span
NOISE_PRESSURE_PA = 300.0    # transducer: about one count of a 1.38 MPa span


TRUTH_CATALOGUE = os.path.join(os.path.dirname(__file__), "..", "..", "..", "host_sim", "blindtest", "truth.json")


def _truth_catalogue():
    with open(TRUTH_CATALOGUE) as fh:
        return {e["name"]: e for e in json.load(fh)["effects"]}


TRUTH = _truth_catalogue()


def truth_params(effect, rng):
    """Random strength within physical ranges (truth.json "draw"), in the truth variant's parameter order."""
    if effect not in TRUTH:
        return []
    return [float(rng.uniform(*p["draw"])) for p in TRUTH[effect]["params"]]


def schedules(rng):
    """Two calibration schedules and one held-out one, all different (900 lb base).
    The held-out step lies between the calibration steps: it tests the fitted
    model on a new schedule, not on heights no calibration run reached. All
    loaded states stay in one hysteresis band of the thesis (1050..1150 lb):
    at 1150 lb the program's 1200 lb line takes over and the platform sinks
    another 2.7 in, a different regime."""
    j = lambda: rng.uniform(-1.0, 1.0)
    base = 900.0 * LB
    return [
        ("cal1", 5.0 + j(), 35.0 + j(), 55.0, base + 240.0 * LB),
        ("cal2", 4.0 + j(), 31.0 + j(), 50.0, base + 150.0 * LB),
        ("hold", 6.0 + j(), 33.0 + j(), 52.0, base + 200.0 * LB),
    ]


def generate_case(sim, effect, seed, folder):
    """Writes cal1.csv, cal2.csv, hold.csv; returns the truth parameters."""
    rng = np.random.default_rng(seed * 1000 + CASES.index(effect))
    params = truth_params(effect, rng)
    for name, t_on, t_off, end, loaded in schedules(rng):
        t = np.round(np.arange(0.0, end + 1e-9, 0.01), 2)
        load = cplant.scenario_loads(t, {"base_load_n": 900.0 * LB, "step_load_n": loaded - 900.0 * LB,
                                         "step_on_s": t_on, "step_off_s": t_off, "end_s": end})
        tr = sim.generate(CONFIG, t, load, effect, params, seed)
        sig = dict(tr.signals)
        sig["height_m"] = sig["height_m"] + rng.normal(0.0, NOISE_HEIGHT_M, len(t))
        for s in ("p_spring_pa", "p_pipe_pa"):
            sig[s] = sig[s] + rng.normal(0.0, NOISE_PRESSURE_PA, len(t))
        sig["p_acc_pa"] = np.full(len(t), np.nan)
        runs.write_run(os.path.join(folder, f"{name}.csv"), t, sig, load, tr.commands, CONFIG, "rig")
    return params


def diagnose_blind(folder, out, extra):
    """The diagnosis as its own process, on the logs only."""
    cmd = [sys.executable, "-m", "leveler.diagnose", "--config", CONFIG,
           "--run", os.path.join(folder, "cal1.csv"), "--run", os.path.join(folder, "cal2.csv"),
           "--holdout", os.path.join(folder, "hold.csv"), "--out", out, "--quiet"] + extra
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode != 0:
        raise RuntimeError(f"diagnosis failed ({p.returncode}): {p.stderr.strip()}")
    with open(os.path.join(out, "diagnosis.json")) as fh:
        return json.load(fh)


def confusion(results):
    lines = ["truth \\ named  " + " ".join(f"{c[:7]:>7}" for c in CASES)]
    for t in CASES:
        row = [sum(1 for r in results if r["truth"] == t and r["named"] == c) for c in CASES]
        lines.append(f"{t:<15}" + " ".join(f"{v:>7}" for v in row))
    return "\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(prog="leveler-blindtest", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", type=int, default=5, help="seeds per case (default 5)")
    ap.add_argument("--first-seed", type=int, default=1)
    ap.add_argument("--cases", default=",".join(CASES), help="comma-separated subset of cases")
    ap.add_argument("--fast", action="store_true", help="smaller fitting budget (the CTest variant)")
    ap.add_argument("--keep", metavar="DIR", help="keep logs, sealed labels and diagnoses here")
    ap.add_argument("--json", metavar="FILE", help="write all results here")
    ap.add_argument("--check", action="store_true", help="exit 1 when a target is missed")
    a = ap.parse_args(argv)
    cases = [c for c in a.cases.split(",") if c]
    for c in cases:
        if c not in CASES:
            ap.error(f"unknown case {c!r} (known: {', '.join(CASES)})")
    sim = make_simulator()
    extra = ["--fast"] if a.fast else []
    top = a.keep or tempfile.mkdtemp(prefix="leveler-blindtest-")
    os.makedirs(top, exist_ok=True)
    results = []
    t_all = time.perf_counter()
    for seed in range(a.first_seed, a.first_seed + a.seeds):
        for case in cases:
            folder = os.path.join(top, f"seed{seed}-{len(results):02d}")
            logs = os.path.join(folder, "logs")
            os.makedirs(logs, exist_ok=True)
            params = generate_case(sim, case, seed, logs)
            # the sealed label: beside the logs, never passed to the diagnosis
            with open(os.path.join(folder, "label.sealed.json"), "w") as fh:
                json.dump({"effect": case, "truth_params": params, "seed": seed}, fh)
            t0 = time.perf_counter()
            d = diagnose_blind(logs, os.path.join(folder, "diagnosis"), extra)
            r = {"seed": seed, "truth": case, "named": d["effect"], "shrink_pct": d["shrink_pct"],
                 "margin_pct": d["margin_pct"], "seconds": time.perf_counter() - t0,
                 "ranking": [(x["effect"], round(x["shrink_pct"], 1)) for x in d["ranking"]]}
            results.append(r)
            ok = "ok " if r["named"] == case else "MISS"
            print(f"{ok} seed {seed} truth {case:<15} named {r['named']:<15} held-out shrink "
                  f"{r['shrink_pct']:6.1f}%  ({r['seconds']:.0f} s)  top: {r['ranking'][:3]}", flush=True)
    print()
    print(confusion(results))
    right = [r for r in results if r["named"] == r["truth"]]
    eff_right = [r["shrink_pct"] for r in right if r["truth"] != "none"]
    none_cases = [r for r in results if r["truth"] == "none"]
    false_named = [r for r in none_cases if r["named"] != "none"]
    hit = 100.0 * len(right) / max(len(results), 1)
    med = float(np.median(eff_right)) if eff_right else float("nan")
    print(f"\nright effect named: {len(right)}/{len(results)} = {hit:.0f}% (target >= 90%)")
    print(f"median held-out shrink when right: {med:.1f}% (target >= 70%)")
    print(f"false effects in none cases: {len(false_named)}/{len(none_cases)} (target 0)")
    print(f"total {time.perf_counter() - t_all:.0f} s; logs and diagnoses in {top}")
    if a.json:
        with open(a.json, "w") as fh:
            json.dump({"results": results, "hit_pct": hit, "median_shrink_pct": med,
                       "false_in_none": len(false_named)}, fh, indent=2)
    if a.check:
        ok = hit >= 90.0 and (not eff_right or med >= 70.0) and not false_named
        return 0 if ok else 1
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Published event figures as the diagnosis's evidence (--features, features.py):
each figure against its simulated value in units of its published resolution; no
noise of their own, no pairs, no experiments."""
import numpy as np

from . import fit
from .evidence import THRESHOLD_PCT, Evidence, sensitivity_floor
from .features import FEATURE_SCALE, KIND

# Which phase each thesis event figure belongs to (for the `where` table of a features run).
FEATURE_PHASE = {
    "height_before_step_m": "steady", "lowest_height_m": "drop", "p2_drop_stop_pa": "drop",
    "time_stuck_bottom_s": "stuck_low", "p2_breakaway_pa": "stuck_low",
    "time_return_after_step_s": "climb", "p2_after_climb_pa": "settle",
    "highest_height_m": "jump", "p2_jump_pa": "jump", "time_stuck_top_s": "stuck_high",
    "p2_start_down_pa": "stuck_high", "time_return_after_removal_s": "return",
}


def feature_table(run, trace):
    """Published figure vs simulated, difference in SI and in resolution units."""
    sim = run.figures(trace)
    rows = []
    for k, v in run.features.items():
        s = sim.get(k)
        rows.append({"run": run.name, "figure": k, "phase": FEATURE_PHASE[k], "published": v, "simulated": s,
                     "difference": None if s is None else s - v,
                     "normalised": None if s is None else (s - v) / FEATURE_SCALE[KIND[k]]})
    return rows


def feature_where(problem, runs):
    rows = []
    for r in runs:
        rows += feature_table(r, problem.simulate(r, None, {}))
    ranked = sorted(rows, key=lambda x: -(abs(x["normalised"]) if x["normalised"] is not None else 1e9))
    for i, x in enumerate(ranked, 1):
        x["rank"] = i
    return {"ranked": ranked, "runs": [{"run": r.name, "features": r.features} for r in runs]}


def _gap(runs, traces):
    return {"normalised": fit.cost_to_gap(np.concatenate([fit.run_residual(r, t) for r, t in zip(runs, traces)]),
                                          len(runs))}


def feature_before_after(problem, runs, nominal, augmented):
    out = {"overall": {"before": _gap(runs, nominal), "after": _gap(runs, augmented)},
           "per_phase": {}, "events": []}
    for r, n, a in zip(runs, nominal, augmented):
        out["events"].append({"run": r.name, "real": r.features, "nominal": r.figures(n),
                              "augmented": r.figures(a)})
    return out


class PublishedFigures(Evidence):
    """A thesis's (or a rig's) published event figures, simulated closed loop on their schedules."""

    noun = "figures"

    def where(self, problem, runs):
        return feature_where(problem, runs)

    def where_line(self, w):
        if w["difference"] is None:
            return f"      #{w['rank']} {w['run']}: {w['figure']} not produced by the simulation"
        return (f"      #{w['rank']} {w['run']}: {w['figure']} off by {w['difference']:+.4g} (SI), "
                f"{w['normalised']:+.1f} x its published resolution")

    def threshold(self, hold_problem, nominal_hold_gap):
        floor = sensitivity_floor(hold_problem, nominal_hold_gap)
        return floor, max(THRESHOLD_PCT, floor)

    before_after = staticmethod(feature_before_after)

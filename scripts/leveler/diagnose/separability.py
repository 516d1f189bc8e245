"""Look-alikes: can these logs tell two fitted candidates apart?

For two leading candidates A and B (both fitted on the calibration runs), the
runs are re-made by the fitted A (its simulation on the runs' own inputs,
no noise) and B is refitted on them, and the other way round. If each
explains the other's simulated data to within what it leaves unexplained in
the real data (its own calibration gap), nothing in these logs separates
them: the diagnosis says so instead of naming one at random, and the
experiment design (design.py) proposes a test that does.
"""
from dataclasses import replace

import numpy as np
from scipy.optimize import least_squares

from . import effects as fx
from .effects import from_unit, to_unit

WITHIN_PTS = 30.0     # a runner-up this close in held-out shrink is a contender
CROSS_NFEV = 30


def simulated_runs(problem, effect, params):
    """The runs as the fitted candidate would have produced them (unmeasured stays unmeasured)."""
    out = []
    for run in problem.runs:
        tr = problem.simulate(run, effect, params)
        sig = {s: np.where(np.isfinite(v), tr.signals.get(s, v), np.nan) for s, v in run.signals.items()}
        out.append(replace(run, path=f"{run.path}#{effect}", signals=sig))
    return out


def cross_fit(problem, data_effect, data_params, effect, start_params):
    """Refit `effect` on the runs `data_effect` would make; returns (gap, params)."""
    e = fx.get(effect)
    sub = type(problem)(problem.sim, problem.config, simulated_runs(problem, data_effect, data_params),
                        problem.mode)
    u0 = to_unit(e, start_params)
    fun = lambda u: sub.residual_vector(effect, from_unit(e, u))
    d = len(u0)
    best_u, best = u0, float(np.sum(fun(u0) ** 2))
    try:
        res = least_squares(fun, u0, bounds=(np.zeros(d), np.ones(d)), diff_step=0.02,
                            x_scale=np.full(d, 0.3), max_nfev=CROSS_NFEV, method="trf")
        if float(np.sum(res.fun ** 2)) < best:
            best_u, best = res.x, float(np.sum(res.fun ** 2))
    except ValueError:
        pass
    problem.nsim += sub.nsim
    return float(np.sqrt(best / max(len(sub.runs), 1))), from_unit(e, best_u)


def _values(entry):
    return {k: v["value"] for k, v in entry["params"].items()}


def contenders(ranking, threshold):
    """The leader and every runner-up that also clears the threshold within WITHIN_PTS."""
    if not ranking or ranking[0]["shrink_pct"] < threshold:
        return []
    lead = ranking[0]
    return [lead] + [r for r in ranking[1:3] if r["shrink_pct"] >= threshold
                     and lead["shrink_pct"] - r["shrink_pct"] <= WITHIN_PTS]


def test_pair(problem, a, b):
    """Evidence for one pair of ranking entries (fitted on problem's runs)."""
    ab_gap, ab_params = cross_fit(problem, a["effect"], _values(a), b["effect"], _values(b))
    ba_gap, ba_params = cross_fit(problem, b["effect"], _values(b), a["effect"], _values(a))
    own_a, own_b = a["calibration_gap"], b["calibration_gap"]
    same = ab_gap <= own_a and ba_gap <= own_b
    return {
        "effects": [a["effect"], b["effect"]],
        "cannot_tell_apart": bool(same),
        # gap of B refitted on A's simulated runs, against A's own gap on the real runs
        "b_on_a_gap": ab_gap, "a_own_gap": own_a,
        "a_on_b_gap": ba_gap, "b_own_gap": own_b,
        "b_on_a_params": ab_params, "a_on_b_params": ba_params,
    }


def lookalikes(problem, ranking, threshold):
    """Pairs among the contenders, tested; the group that cannot be told from the leader."""
    group = contenders(ranking, threshold)
    tests = [test_pair(problem, group[0], other) for other in group[1:]]
    alike = [group[0]["effect"]] + [t["effects"][1] for t in tests if t["cannot_tell_apart"]] if group else []
    return {"tests": tests, "group": alike if len(alike) > 1 else []}

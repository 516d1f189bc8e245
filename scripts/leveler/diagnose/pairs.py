"""Two effects at once: pairs fitted on top of the best single candidate, and
the rule that keeps a second effect.

After the single candidates are fitted and ranked, the leader is paired with
each other candidate that is plausible on its own (it shrinks the calibration
gap), at most MAX_PAIRS of them in ranking order, and each pair is fitted
jointly from the two single fits (fit.fit_pairs). This is done whether or not
the leader alone clears the threshold: two effects that partly cancel may
each look weak alone. It is skipped when the leader leaves less of the
held-out gap than rule 1 asks a second effect to close.

A second effect is kept only when it buys more than its extra parameters:
  1. held out: the pair closes at least REL_GAIN of the held-out gap the
     leader alone leaves (a dominant leader leaves little, and what it leaves
     is partly sensor noise no model removes), at least MIN_GAIN_PTS points of
     the nominal gap, and shrinks it by at least the threshold a single effect
     must clear (sensitivity floor included);
  2. calibration: the Bayesian information criterion on the calibration
     residuals falls, n ln(SS_pair / SS_leader) + k ln(n) < 0, with k the
     second's parameter count and n the effective number of independent
     samples (autocorrelated residuals count less, as in the intervals);
  3. neither effect alone makes the held-out gap worse than nominal (no
     candidate that does is ever named).
Of the pairs that pass, the one with the largest held-out shrink is kept.
"""
import math

from . import effects as fx
from . import fit

MAX_PAIRS = 3      # pairs fitted on top of the leader (time: about a single fit each)
REL_GAIN = 0.3     # share of the leader's held-out gap a second effect must close
MIN_GAIN_PTS = 5.0  # and at least this many points of the nominal gap


def plan(ranking, fits):
    """{"leader+second": joint-fit starts} for the plausible seconds of the leader;
    none when the leader leaves less than MIN_GAIN_PTS of the held-out gap to gain."""
    if ranking[0]["shrink_pct"] > 100.0 - MIN_GAIN_PTS:
        return {}
    leader = ranking[0]["effect"]
    seconds = [r["effect"] for r in ranking[1:] if r["calibration_shrink_pct"] > 0.0][:MAX_PAIRS]
    return {fx.combine([leader, s]): fit.pair_starts(fx.get(leader), fx.get(s), fits[leader]["unit"],
                                                       fits[s]["unit"])
            for s in seconds}


def entry(name, res, by_effect, nruns, shrink, nominal_cal_gap, nominal_hold_gap):
    """A fitted pair as diagnosis.json reports it (as a ranking entry, plus the
    held-out gain over its leader and the information criterion)."""
    first, second = fx.parts(name)
    lead = by_effect[first]
    ss_lead = lead["calibration_gap"] ** 2 * nruns
    n = max(res["calibration_n_eff"], 1.0)
    k = len(fx.get(second).params)
    d_bic = (n * math.log(res["calibration_ss"] / ss_lead) + k * math.log(n)
             if ss_lead > 0 and res["calibration_ss"] > 0 else math.inf)
    out = {
        "effect": name, "effects": [first, second],
        "params": {p.name: dict({"value": res["params"][p.name], "lo": p.lo, "hi": p.hi},
                                **res["uncertainty"][p.name])
                   for p in fx.get(name).params},
        "calibration_gap": res["calibration_gap"],
        "calibration_shrink_pct": shrink(nominal_cal_gap, res["calibration_gap"]),
        "holdout_gap": res["holdout_gap"],
        "shrink_pct": shrink(nominal_hold_gap, res["holdout_gap"]),
        "delta_bic": d_bic, "effective_samples": n,
        "simulations": res["simulations"], "seconds": res["seconds"],
    }
    out["gain_pts"] = out["shrink_pct"] - lead["shrink_pct"]
    out["closes_pct_of_leader_gap"] = 100.0 * (1.0 - res["holdout_gap"] / lead["holdout_gap"]) \
        if lead["holdout_gap"] > 0 else 0.0
    return out


def judge(entries, by_effect, threshold):
    """Marks each pair kept or not (with the reasons it fails); returns the kept one or None."""
    for e in entries:
        first, second = e["effects"]
        why = []
        if not e["closes_pct_of_leader_gap"] >= 100.0 * REL_GAIN:
            why.append(f"closes {e['closes_pct_of_leader_gap']:.0f}% of the leader's held-out gap "
                       f"< {100.0 * REL_GAIN:.0f}%")
        if not e["gain_pts"] >= MIN_GAIN_PTS:
            why.append(f"held-out gain {e['gain_pts']:+.1f} points < {MIN_GAIN_PTS:g}")
        if not e["shrink_pct"] >= threshold:
            why.append(f"held-out shrink {e['shrink_pct']:.1f}% < threshold {threshold:.1f}%")
        if not e["delta_bic"] < 0.0:
            why.append(f"information criterion {e['delta_bic']:+.1f} >= 0 (the fit gain does not pay "
                       f"for {second}'s parameters)")
        for name in (first, second):
            if not by_effect[name]["shrink_pct"] > 0.0:
                why.append(f"{name} alone makes the held-out gap worse than nominal")
        e["kept"], e["why_not"] = False, why
    ok = [e for e in entries if not e["why_not"]]
    if not ok:
        return None
    best = max(ok, key=lambda e: e["shrink_pct"])
    best["kept"] = True
    return best

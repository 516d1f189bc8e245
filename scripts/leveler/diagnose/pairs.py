"""Two effects at once: pairs fitted on top of the best single candidate, the
rule that keeps a second effect, and the ranked second effect.

After the single candidates are fitted and ranked, the leader is paired with
every other candidate in a brief screening fit (fit.fit_pairs, screen): a
second effect is whatever best explains what the leader leaves, and that need
not be a good single candidate (a single fit that mimics the leader ranks high
alone and explains nothing the leader leaves). This is done whether or not the
leader alone clears the threshold: two effects that partly cancel may each
look weak alone.

The ranked second (`second` in diagnosis.json) is the partner whose pair has
the most evidence over the leader alone, in log-likelihood units over all runs:
  evidence = n_c ln(SS_pair / SS_leader) + k ln(n_c)    (calibration, BIC)
           + n_h ln(SS_pair / SS_leader)                (held out, no penalty)
with k the second's parameter count and n the effective numbers of independent
samples (autocorrelated residuals count less, as in the intervals). Negative
is evidence for the pair. Both parts count: when the leader leaves little of the
held-out gap, that run is mostly sensor noise and the calibration runs carry
the evidence; a second that only fits the calibration runs loses it held out.

The MAX_PAIRS partners with the most evidence that could be kept (rule 3) get
a full joint fit, unless the leader leaves less of the held-out gap than rule 1
asks a second effect to close. A second effect is kept (named, `effects`)
only when it buys more than its extra parameters:
  1. held out: the pair closes at least REL_GAIN of the held-out gap the
     leader alone leaves (a dominant leader leaves little, and what it leaves
     is partly sensor noise no model removes), at least MIN_GAIN_PTS points of
     the nominal gap, and shrinks it by at least the threshold a single effect
     must clear (sensitivity floor included);
  2. calibration: the Bayesian information criterion on the calibration
     residuals falls (the first term of the evidence above is < 0);
  3. neither effect alone makes the held-out gap worse than nominal (no
     candidate that does is ever named);
  4. told apart: it closes REL_GAIN of the first's held-out gap more than any
     other partner of the same first does (screening fits included). A leader
     whose form is not the truth's leaves a residual that any flexible partner
     partly fits; then several partners close much of it and none is the second
     effect (offform seeds 3-4: a false second in 7 of 30 single cases, each
     within 27 points of another partner; true pairs 36 points or more ahead).
     A pair failing only this still explains the held-out runs (the
     `unexplained` check takes it): the second effect is there, which one is not.
Of the fully fitted pairs that pass, the one with the largest held-out shrink is kept.

A second round: when the pairs on top of the leader still leave the held-out runs
over UNEXPLAINED_NOISE noise gaps, the leader may be standing in for two other effects
(a pipe delay beside a sensor lag named a thermal effect: thermal + sensor_lag left
0.810, the true pair 0.447, never fitted). The leader's best partner then leads a
round of its own, without the leader; its pairs are judged with the first round's,
and must also do what rule 1 asks of a pair on top of the leader.
"""
import math

from . import effects as fx
from . import fit
from .confidence import UNEXPLAINED_NOISE, leaves_much

MAX_PAIRS = 2      # full joint fits on top of the leader (time: about a single fit each)
REL_GAIN = 0.3     # share of the leader's held-out gap a second effect must close
MIN_GAIN_PTS = 5.0  # and at least this many points of the nominal gap


def screen_plan(ranking, fits):
    """{"leader+other": joint-fit starts} for every other candidate."""
    leader = ranking[0]["effect"]
    return {fx.combine([leader, r["effect"]]): fit.pair_starts(fx.get(leader), fx.get(r["effect"]),
                                                                fits[leader]["unit"], fits[r["effect"]]["unit"])
            for r in ranking[1:]}


def plan(ranking, screened, results):
    """{"leader+second": starts} for the full fits: the MAX_PAIRS screened pairs with
    the most evidence whose effects may be named, each continued from its screening
    fit (which polished every start briefly); none when the leader leaves less than
    MIN_GAIN_PTS of the held-out gap to gain."""
    if ranking[0]["shrink_pct"] > 100.0 - MIN_GAIN_PTS:
        return {}
    by = {r["effect"]: r for r in ranking}
    ok = [e for e in screened if all(by[n]["shrink_pct"] > 0.0 for n in e["effects"])]
    best = sorted(ok, key=lambda e: e["evidence"])[:MAX_PAIRS]
    return {e["effect"]: [results[e["effect"]]["unit"]] for e in best}


def _log_ratio(n, ss_pair, ss_lead):
    return n * math.log(ss_pair / ss_lead) if ss_pair > 0 and ss_lead > 0 else math.inf


def entry(name, res, by_effect, nruns, shrink, nominal_cal_gap, nominal_hold_gap, screen=False):
    """A fitted pair as diagnosis.json reports it (as a ranking entry, plus the
    held-out gain over its leader, the information criterion and the evidence)."""
    first, second = fx.parts(name)
    lead = by_effect[first]
    n = max(res["calibration_n_eff"], 1.0)
    d_bic = _log_ratio(n, res["calibration_ss"], lead["calibration_gap"] ** 2 * nruns[0]) \
        + len(fx.get(second).params) * math.log(n)
    d_hold = _log_ratio(max(res["holdout_n_eff"], 1.0), res["holdout_ss"], lead["holdout_gap"] ** 2 * nruns[1])
    out = {
        "effect": name, "effects": [first, second], "screen": screen,
        "params": {p.name: dict({"value": res["params"][p.name], "lo": p.lo, "hi": p.hi},
                                **res["uncertainty"].get(p.name, {}))
                   for p in fx.get(name).params},
        "calibration_gap": res["calibration_gap"],
        "calibration_shrink_pct": shrink(nominal_cal_gap, res["calibration_gap"]),
        "holdout_gap": res["holdout_gap"],
        "shrink_pct": shrink(nominal_hold_gap, res["holdout_gap"]),
        "delta_bic": d_bic, "effective_samples": n, "evidence": d_bic + d_hold,
        "simulations": res["simulations"], "seconds": res["seconds"], "kept": False,
        "why_not": ["screening fit only"] if screen else [],
    }
    out["closes_pct_of_leader_gap"], out["gain_pts"] = _over(out, lead)
    return out


def _over(e, single):
    """What a pair (or any held-out entry) does over a single effect's fit: the share
    of its held-out gap closed, %, and the held-out shrink gained, points."""
    closes = 100.0 * (1.0 - e["holdout_gap"] / single["holdout_gap"]) if single["holdout_gap"] > 0 else 0.0
    return closes, e["shrink_pct"] - single["shrink_pct"]


def ranked_second(entries, kept, leader=None):
    """The second place of the ranked combination: the kept pair's second, else the
    partner with the most evidence over the leader alone (None without pairs). A
    second round's evidence is over its own first, not the leader: without a kept
    pair only pairs on top of the leader (its name: leader) are ranked."""
    ranked = [e for e in entries if leader is None or e["effects"][0] == leader]
    best = kept or min(ranked, key=lambda e: e["evidence"], default=None)
    if best is None:
        return None
    return {"effect": best["effects"][1], "pair": best["effect"], "kept": best["kept"],
            "evidence": best["evidence"], "gain_pts": best["gain_pts"],
            "closes_pct_of_leader_gap": best["closes_pct_of_leader_gap"]}


def second_round(ranking, entries, kept, noise):
    """The ranking a second round of pairs is fitted on (its leader first), or None.
    The round runs when the pairs on top of the leader leave the held-out runs over
    UNEXPLAINED_NOISE noise gaps (the kept one, else the best of them): the leader may then
    stand in for two other effects (a pipe delay beside a sensor lag named a thermal
    effect with the sensor lag, its pair a third worse than the two true effects'),
    and the leader's best partner (the most evidence over the leader) leads the
    round, with every candidate but the leader."""
    if not entries or not leaves_much(kept or min(entries, key=lambda e: e["holdout_gap"]), noise):
        return None
    lead = ranking[0]["effect"]
    partner = ranked_second(entries, None, lead)["effect"]
    again = [r for r in ranking if r["effect"] == partner] + \
        [r for r in ranking if r["effect"] not in (lead, partner)]
    return again if len(again) > 1 else None


def _beats_leader(e, lead):
    """Why a pair of a second round (its first not the leader) does not do for the
    leader alone what rule 1 asks of a second effect: [] when it does."""
    if e["effects"][0] == lead["effect"]:
        return []
    closes, gain = _over(e, lead)
    if closes >= 100.0 * REL_GAIN and gain >= MIN_GAIN_PTS:
        return []
    return [f"closes {closes:.0f}% of the held-out gap {lead['effect']} alone leaves ({gain:+.1f} points): "
            f"less than a second effect must on top of it"]


def _rival(e, others):
    """The other partner of e's first that closes the most of its held-out gap, or None."""
    same = [o for o in others if o["effects"][0] == e["effects"][0] and o["effect"] != e["effect"]]
    return max(same, key=lambda o: o["closes_pct_of_leader_gap"], default=None)


def _told_apart(e, others):
    """Why e's second is not told apart from another partner (rule 4): [] when it is."""
    rival = _rival(e, others)
    if rival is None:
        return []
    ahead = e["closes_pct_of_leader_gap"] - rival["closes_pct_of_leader_gap"]
    e["ahead_of"] = {"partner": rival["effects"][1], "points": ahead}
    if ahead >= 100.0 * REL_GAIN:
        return []
    return [f"not told apart from {rival['effects'][1]}: closes {ahead:.0f} points more of "
            f"{e['effects'][0]}'s held-out gap than it{' (screening fit)' if rival.get('screen') else ''} "
            f"< {100.0 * REL_GAIN:.0f}"]


def judge(entries, by_effect, threshold, max_gap=float("inf"), leader=None, others=()):
    """Marks each pair kept or not (with the reasons it fails); returns the kept one or None.
    max_gap: the held-out gap a kept pair must get below (the noise gate, pipeline.py);
    leader: the best single effect, which a pair of a second round must beat as a pair
    on top of it would (second_round); others: every pair fitted (screening fits too),
    the partners a second effect must be told apart from (rule 4). A pair failing only
    rule 4 is marked `explains`."""
    for e in entries:
        first, second = e["effects"]
        why = _beats_leader(e, by_effect[leader]) if leader else []
        if not e["closes_pct_of_leader_gap"] >= 100.0 * REL_GAIN:
            why.append(f"closes {e['closes_pct_of_leader_gap']:.0f}% of {first}'s held-out gap "
                       f"< {100.0 * REL_GAIN:.0f}%")
        if not e["gain_pts"] >= MIN_GAIN_PTS:
            why.append(f"held-out gain {e['gain_pts']:+.1f} points < {MIN_GAIN_PTS:g}")
        if not e["shrink_pct"] >= threshold:
            why.append(f"held-out shrink {e['shrink_pct']:.1f}% < threshold {threshold:.1f}%")
        if not e["holdout_gap"] <= max_gap:
            why.append(f"held-out gap {e['holdout_gap']:.3f} not below {max_gap:.3f} (the logs' noise)")
        if not e["delta_bic"] < 0.0:
            why.append(f"information criterion {e['delta_bic']:+.1f} >= 0 (the fit gain does not pay "
                       f"for {second}'s parameters)")
        for name in (first, second):
            if not by_effect[name]["shrink_pct"] > 0.0:
                why.append(f"{name} alone makes the held-out gap worse than nominal")
        apart = _told_apart(e, list(others) + list(entries))
        e["kept"], e["why_not"], e["explains"] = False, why + apart, bool(apart) and not why
    ok = [e for e in entries if not e["why_not"]]
    if not ok:
        return None
    best = max(ok, key=lambda e: e["shrink_pct"])
    best["kept"] = True
    for e in ok:
        if e is not best:
            e["why_not"] = [f"{best['effect']} shrinks the held-out gap more"]
    return best


def explaining(entries, kept):
    """What the unexplained check takes as the pairs' best: the kept pair, else the
    pair with the largest held-out shrink that failed only rule 4 (a second effect
    not told apart from another partner still explains the runs), else None."""
    return kept or max((e for e in entries if e.get("explains")), key=lambda e: e["shrink_pct"], default=None)

"""How sure the verdict is, said in a way that is true, and what no candidate explains.

A level, from what the logs show about the verdict (not from the verdict's
name): the named effect's margin over the next candidate, whether a look-alike
was found, how much of the calibrated model's gap it closes, and how close the
result is to the logs' own noise. Each level carries the probability of being
right measured for it on the blind test's second truth family (forms written
apart from the candidates, host_sim/blindtest/truth2.json; data/confidence.json,
docs/diagnosis.md): "sure" is said only where that was right at least 19 times
in 20. Below "sure", the set the logs cannot separate, why, and the experiment
(experiment.csv) that would. An effect whose parameters the logs pin none of is
`unsure` with "not explained" in its set (pinned).

"Not explained by any candidate": the calibrated model leaves a gap well above
the noise, and the best candidate closes less than half of it while what it
leaves is still above the noise (three noise gaps, as for the gap), or less than two
thirds while what it leaves is still far above the noise (a part of the gap is a
look-alike's, the rest is not), or it closes the gap in some phases by making
others worse (a stand-in bent to fit, not the cause). The verdict then names no
effect (the nearest look-alike is kept as `nearest`), with where the residual lies.
"""
import json
import os

from .evidence import FLOOR_MARGIN_PTS, THRESHOLD_PCT

LEVELS_FILE = os.path.join(os.path.dirname(__file__), "data", "confidence.json")

SURE_MARGIN_PTS = 25.0      # the named effect beats the next candidate by this many held-out points
LIKELY_MARGIN_PTS = 10.0
SURE_EFFECT_SHRINK = 60.0   # and closes this much of what the calibrated model leaves
EXPLAINS_PCT = 50.0         # a candidate closing less than half of a gap above noise does not explain it
UNEXPLAINED_NOISE = 3.0     # "above noise": a held-out gap this many times the logs' noise gap
# A candidate closing less than two thirds that leaves more than LEFT_NOISE noise
# gaps explains part of the gap, not the logs. From the present truths: a right
# answer there left at most 8 noise gaps, and those closing under two thirds
# (weak area truths) left about one.
PARTLY_PCT = 200.0 / 3.0
LEFT_NOISE = 10.0
# A candidate that adds to the residual of the phases it makes worse more than a fifth
# of the model's it was fitted on (per-phase RMS, summed) is bent to fit, not the cause.
# From the present truths: a right answer there added at most 0.13 (valve dynamics at
# 1000 lb); a stiffness outside the catalogue fitted as friction adds 0.2-0.5.
WORSENS_SHARE = 0.2
NONE_QUIET = 1.3            # a `none` is sure when what is left is within 1.3 noise gaps (the true model: ~1)
# ... and the calibration moved values of at most this many parts of the rig (config
# sections: the damper's two coefficients are one part): each value it moves can take up
# part of an effect, and with two parts an effect beside one mis-set value explained the
# logs as well (a valve whose Cd falls with the pressure ratio calibrated as the vent's
# Cd beside a mis-set spring volume, both within the noise).
NONE_SURE_PARTS = 1
# ... and it moved some value by a change the report calls material
# (calibrate.MATERIAL_REL): a calibration kept only for changes under it closed a gap
# a few noise gaps wide, as a weak effect leaves (a pipe of lumped segments at 1000 lb,
# 3.3 noise gaps, closed to 1.1 by the compressor +0.3 % and n -0.9 %).


def _measured():
    """Per level, right / cases on the second truth family (written by the blind test's --report)."""
    try:
        with open(LEVELS_FILE) as fh:
            return json.load(fh)
    except (OSError, ValueError):
        return {}


def _probability(level):
    m = _measured().get(level)
    if not m or not m.get("cases"):
        return None
    return {"p": m["right"] / m["cases"], "right": m["right"], "cases": m["cases"], "measured_on": m.get("on", "")}


def worsened(entry, per_phase):
    """The share of a model's residual (per-phase RMS `before`, summed) that a
    candidate fitted on that model adds in the phases it makes worse (its
    per_phase_shrink_pct, on the same held-out runs and the same model), and those
    phases, most added first; (0.0, []) without a per-phase signature."""
    shrink = entry.get("per_phase_shrink_pct") or {}
    total = sum(v["before"] for v in per_phase.values())
    added = {p: -per_phase[p]["before"] * s / 100.0 for p, s in shrink.items() if p in per_phase and s < 0.0}
    if total <= 0.0:
        return 0.0, []
    return sum(added.values()) / total, sorted(added, key=lambda p: -added[p])


def above_noise(gap, noise):
    """A held-out gap above the logs' noise: more than UNEXPLAINED_NOISE noise gaps."""
    return noise > 0 and gap > UNEXPLAINED_NOISE * noise


def unexplained(ranking, cal_gap, noise, per_phase, threshold):
    """The 'not explained by any candidate' finding, or None. ranking: held-out
    shrink of each candidate over the calibrated model (cal_gap)."""
    best = ranking[0]
    if not above_noise(cal_gap, noise):
        return None
    left = cal_gap * (1.0 - best["shrink_pct"] / 100.0) / noise
    partly = best["shrink_pct"] < PARTLY_PCT and left > LEFT_NOISE
    # under half, but what is left within the noise: all that is above it is explained
    under_half = best["shrink_pct"] < EXPLAINS_PCT and left > UNEXPLAINED_NOISE
    # measured by evidence_runs.signatures on the model the candidate was fitted on;
    # absent where the ranking moved to another model (the calibration's)
    share, worse = best.get("worsened_share", 0.0), best.get("worsened_phases", [])
    bent = share > WORSENS_SHARE
    if not (under_half or partly or bent):
        return None
    where = sorted(per_phase.items(), key=lambda kv: -kv[1]["before"])[:3]
    short = (f"less than {EXPLAINS_PCT:.0f}%" if under_half else
             f"less than two thirds, and leaves {left:.1f} times the noise" if partly else
             f"by making {', '.join(worse)} worse: {100 * share:.0f}% of the residual added where it fits worse")
    return {"gap": cal_gap, "noise_gap": noise, "times_noise": cal_gap / noise, "worsened_share": share,
            "nearest": best["effect"], "nearest_shrink_pct": best["shrink_pct"], "left_times_noise": left,
            "where": [{"phase": p, "gap": v["before"]} for p, v in where],
            "why": (f"the calibrated model leaves a held-out gap {cal_gap / noise:.1f} times the logs' noise; "
                    f"the nearest candidate, {best['effect']}, closes {best['shrink_pct']:.0f}% of it "
                    f"({short})" + ("" if best["shrink_pct"] >= threshold else ", below the threshold"))}


def _contenders(ranking, lead_pct, pts):
    return [r["effect"] for r in ranking if r["shrink_pct"] >= lead_pct - pts]


def hinted(effects, ranking, threshold, unexplained_finding=None, gap_above_noise=False):
    """With no effect named, the candidate that closes the threshold's share of the
    held-out gap but was not named (its gain under the noise gate, or another rule):
    these logs hint at it and cannot confirm it, so `none` and it are a set an
    experiment can separate. With a held-out gap above the noise (gap_above_noise,
    more than UNEXPLAINED_NOISE noise gaps) also the candidate that falls short of the
    threshold by less than its margin over the sensitivity floor (and closes
    THRESHOLD_PCT at least): something is there, and it beats what a start state moved
    within its uncertainty closes. None otherwise."""
    if effects or unexplained_finding or not ranking or threshold is None:
        return None
    need = max(THRESHOLD_PCT, threshold - FLOOR_MARGIN_PTS) if gap_above_noise else threshold
    return ranking[0] if ranking[0]["shrink_pct"] >= need else None


def assess(effects, ranking, cal_gap, noise, lookalikes, experiment, unexplained_finding, rival=None,
           alike_values=None, moved=None, threshold=None, unmoved=False, resolved=True):
    """{level, probability, set, why, experiment}. effects: the named effect(s)
    ([] for none); ranking: candidates by held-out shrink over the calibrated model;
    rival: an effect that, on the config as given, explains the held-out runs as
    well as the kept calibration (calibration_path.effect_first); alike_values: the kept
    calibration's moved values and the others that alone explain the runs as well
    as its first ([name, ...], certainty.alike_names); moved: the kept calibration's
    moved values by part of the rig ({section: [name, ...]}, certainty.moved_parts);
    threshold: the share (%) of the held-out gap an effect must close (hinted);
    unmoved: a calibration was kept with no value moved materially; resolved: False
    when the held-out logs replay above their noise even with the right model
    (cplant.floor_above_noise): there a quiet gap is no proof of no effect."""
    best = ranking[0]
    runner = ranking[1] if len(ranking) > 1 else None
    margin = best["shrink_pct"] - runner["shrink_pct"] if runner else 100.0
    left = cal_gap * (1.0 - best["shrink_pct"] / 100.0)
    exp = (experiment or {}).get("ranked", [{}])[0].get("schedule") if experiment else None
    if unexplained_finding:
        level, cset, why = "unsure", [], unexplained_finding["why"]
    elif rival:
        level = "unsure"
        cset = list(dict.fromkeys(list(effects) + ["calibration: " + ", ".join(rival["moved"])] + [rival["effect"]]))
        why = (f"mis-set {', '.join(rival['moved'])} and {rival['effect']} explain the held-out runs about as "
               f"well (held-out gaps {rival['calibration_gap']:.3f} and {rival['effect_gap']:.3f})")
    elif not effects and alike_values:
        level, cset = "unsure", ["calibration: " + n for n in alike_values]
        why = (f"no effect; which of {', '.join(alike_values)} is set wrong these logs cannot tell: "
               f"values outside the calibration's explain the held-out runs about as well alone")
    elif hinted(effects, ranking, threshold, gap_above_noise=above_noise(cal_gap, noise)):
        level, cset = "unsure", [best["effect"], "none"]
        why = (f"no effect named, but {best['effect']} closes {best['shrink_pct']:.0f}% of the held-out gap "
               f"(an effect must close {threshold:.0f}%) by less than these logs can confirm: an experiment "
               f"tells it from none")
    elif not effects and noise > 0 and cal_gap <= NONE_QUIET * noise and len(moved or {}) > NONE_SURE_PARTS:
        names = [n for part in moved.values() for n in part]
        level, cset = "likely", ["calibration: " + n for n in names] + [best["effect"]]
        why = (f"the calibrated model is within the logs' noise, but it moved values of {len(moved)} parts "
               f"({', '.join(names)}): an effect beside fewer mis-set values may explain the logs as well")
    elif not effects and unmoved and noise > 0 and cal_gap <= NONE_QUIET * noise:
        level, cset = "likely", ["none"] + [r["effect"] for r in ranking[:2]]
        why = ("the calibrated model is within the logs' noise, but only through values each moved less than "
               "the report calls a change: a weak effect may leave what they closed")
    elif not effects and not resolved and noise > 0 and cal_gap <= NONE_QUIET * noise:
        level, cset = "likely", ["none"] + [r["effect"] for r in ranking[:2]]
        why = ("the calibrated model is within the logs' noise, but on rig-rate logs with the accumulator's "
               "bursts even the right model replays no closer: a weak effect may hide there")
    elif not effects:
        quiet = noise > 0 and cal_gap <= NONE_QUIET * noise
        level = "sure" if quiet else "likely"
        cset = [] if quiet else _contenders(ranking, best["shrink_pct"], LIKELY_MARGIN_PTS)[:3]
        why = ("the calibrated model is within the logs' noise: nothing is left to explain" if quiet else
               f"no candidate reaches the threshold; the gap left is {cal_gap / noise:.1f} times the noise"
               if noise > 0 else "no candidate reaches the threshold")
    elif lookalikes:
        level, cset = "unsure", list(lookalikes)
        why = "these candidates explain the logs equally well (each refitted on the other's runs)"
    elif not pinned(ranking, effects[0]):
        level, cset = "unsure", [effects[0], "not explained"]
        why = (f"{effects[0]} closes {best['shrink_pct']:.0f}% of the held-out gap, but these logs pin none of "
               f"its parameters (each 95 % interval wider than its range): something acts as it would, its "
               f"size is not seen")
    elif (margin >= SURE_MARGIN_PTS and best["shrink_pct"] >= SURE_EFFECT_SHRINK
          and (noise <= 0 or left <= UNEXPLAINED_NOISE * noise)):
        level, cset = "sure", list(effects)
        why = (f"{best['effect']} closes {best['shrink_pct']:.0f}% of the calibrated model's held-out gap, "
               f"{margin:.0f} points ahead of {runner['effect'] if runner else 'nothing'}")
    else:
        level = "likely" if margin >= LIKELY_MARGIN_PTS else "unsure"
        cset = _contenders(ranking, best["shrink_pct"], SURE_MARGIN_PTS)[:3]
        why = (f"{best['effect']} leads {runner['effect'] if runner else ''} by {margin:.0f} held-out points"
               f"{'' if best['shrink_pct'] >= SURE_EFFECT_SHRINK else ' and closes ' + format(best['shrink_pct'], '.0f') + '% of the gap'}")
    return {"level": level, "probability": _probability(level), "set": cset, "why": why,
            "experiment": exp if level != "sure" else None}


def pinned(ranking, name):
    """Whether the logs pin at least one parameter of the named effect (its single fit's
    identifiable flags; true without them, as on published figures). A parallel
    stiffness outside the catalogue was named friction with a Coulomb force anywhere in
    0..800 N (any friction large enough holds the platform where the stiffness does);
    a true friction's was 43.5 +- 1.8 N."""
    entry = next((r for r in ranking if r["effect"] == name), None)
    flags = [v.get("identifiable", True) for v in ((entry or {}).get("params") or {}).values()]
    return not flags or any(flags)


def leaves_much(entry, noise):
    """An entry (a single effect's fit or a pair) leaves a held-out gap well above the
    logs' noise (UNEXPLAINED_NOISE noise gaps): part of the gap is not its."""
    return above_noise(entry["holdout_gap"], noise)

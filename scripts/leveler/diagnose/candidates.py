"""The candidate effects in the diagnosis: each fitted on the calibration runs and
ranked by held-out shrink, then pairs on top of the leader (pairs.py)."""
from . import effects as fx
from . import fit
from . import pairs
from .gap import shrink


def values_of(entry):
    """A ranking entry's fitted parameter values, {name: value}."""
    return {k: v["value"] for k, v in entry["params"].items()}


def scored(candidates, fits, nominal_cal_gap, nominal_hold_gap):
    """Ranking entries of fitted candidates (fit.fit_all results), shrink against the given gaps."""
    ranking = []
    for name in candidates:
        r = fits[name]
        e = fx.get(name)
        ranking.append({
            "effect": name,
            "params": {p.name: dict({"value": r["params"][p.name], "lo": p.lo, "hi": p.hi},
                                    **r["uncertainty"][p.name])
                       for p in e.params},
            "calibration_gap": r["calibration_gap"],
            "calibration_shrink_pct": shrink(nominal_cal_gap, r["calibration_gap"]),
            "holdout_gap": r["holdout_gap"],
            "shrink_pct": shrink(nominal_hold_gap, r["holdout_gap"]),
            "simulations": r["simulations"],
            "seconds": r["seconds"],
        })
    return ranking


def rank(ranking, resolution_s=0.0):
    """Sorts by held-out shrink, best first, and numbers the places. An effect whose
    fitted strokes all last less than the logs' sample interval resolution_s
    (effects.Effect.resolved) is marked `under_resolution` and ranked after those
    the logs resolve: it cannot be told from the logs' own switch timing."""
    for r in ranking:
        if not fx.get(r["effect"]).resolved(values_of(r), resolution_s):
            r["under_resolution"] = True
        else:
            r.pop("under_resolution", None)
    ranking.sort(key=lambda x: (x.get("under_resolution", False), -x["shrink_pct"]))
    for i, r in enumerate(ranking, 1):
        r["rank"] = i


def effects_step(ask, evidence, calib, holdout, hold_problem, gaps):
    """[3] every candidate fitted on the calibration runs (on the config as given),
    scored on the held-out runs; ranked by held-out shrink. Returns (ranking, fits)."""
    nominal_cal_gap, nominal_hold_gap = gaps
    progress = ask.progress
    progress(f"[3/4] fitting {len(ask.candidates)} candidate effect(s) on {len(calib)} run(s), "
             f"scoring on {len(holdout)} held-out run(s)")
    done = [0]

    def on_fit(name, r):
        done[0] += 1
        progress(f"      {done[0]}/{len(ask.candidates)} {name:<15} held-out gap {r['holdout_gap']:.3f} "
                 f"(nominal {nominal_hold_gap:.3f}, {shrink(nominal_hold_gap, r['holdout_gap']):+.1f}%) "
                 f"in {r['seconds']:.1f} s")

    fits = fit.fit_all(ask.spec, ask.config, calib, holdout, ask.mode, ask.candidates, ask.jobs, on_fit,
                       ask.fit_opts)
    ranking = scored(ask.candidates, fits, nominal_cal_gap, nominal_hold_gap)
    evidence.signatures(holdout, hold_problem, ranking)
    rank(ranking, ask.resolution_s)
    return ranking, fits


def _fit_pairs(ask, basis, plan, screen):
    """Fits the planned pairs and returns ({name: fit result}, [pair entries])."""
    nominal_gaps = basis.gaps

    def on_pair(name, r):
        ask.progress(f"      {name:<31} held-out gap {r['holdout_gap']:.3f} "
                     f"({shrink(nominal_gaps[1], r['holdout_gap']):+.1f}%) in {r['seconds']:.1f} s")

    res = fit.fit_pairs(ask.spec, basis.work, basis.calib, basis.holdout, plan, ask.mode, ask.jobs, on_pair,
                        ask.fit_opts, screen)
    by = {r["effect"]: r for r in basis.ranking}
    return res, [pairs.entry(n, res[n], by, (len(basis.calib), len(basis.holdout)), shrink, *nominal_gaps, screen)
                 for n in plan]


def _pair_round(ask, basis, ranking):
    """Pairs on top of ranking[0]: a screening fit of each, then full joint fits of
    the best (pairs.plan). Returns ({name: entry}, [the fully fitted entries])."""
    screen = pairs.screen_plan(ranking, basis.fits)
    if not screen:
        return {}, []
    ask.progress(f"      pairs on top of {ranking[0]['effect']}: screening {len(screen)}")
    res, screened = _fit_pairs(ask, basis, screen, True)
    full = pairs.plan(ranking, screened, res)
    entries = {e["effect"]: e for e in screened}
    if full:
        ask.progress(f"      fitting {len(full)} of them jointly in full")
        entries.update({e["effect"]: e for e in _fit_pairs(ask, basis, full, False)[1]})
    return entries, [entries[n] for n in full]


def pair_step(ask, basis, gate=0.0, noise=0.0):
    """Pairs on top of the leader: a screening fit of each to rank the second
    effect, full joint fits of the best to judge (pairs.py). When the best of them
    still leaves the held-out runs well above the logs' noise (pairs.UNEXPLAINED_NOISE
    noise gaps), the leader may be a stand-in for two others: pairs on top of its
    best partner follow, judged with the first (pairs.second_round). Returns
    (pair entries ranked by evidence, the kept one or None, the ranked second or None)."""
    ranking = basis.ranking
    entries, full = _pair_round(ask, basis, ranking)
    if not entries:
        return [], None, None
    by = {r["effect"]: r for r in ranking}
    kept = pairs.judge(full, by, basis.threshold, basis.gaps[1] - gate, others=entries.values())
    again = pairs.second_round(ranking, list(entries.values()), kept, noise)
    if again:
        ask.progress(f"      the pairs on top of {ranking[0]['effect']} leave the held-out runs over "
                     f"{pairs.UNEXPLAINED_NOISE:g} noise gaps: pairs on top of {again[0]['effect']}, without "
                     f"{ranking[0]['effect']}")
        more, full2 = _pair_round(ask, basis, again)
        entries.update(more)
        kept = pairs.judge(full + full2, by, basis.threshold, basis.gaps[1] - gate, ranking[0]["effect"],
                           entries.values())
    out = sorted(entries.values(), key=lambda e: e["evidence"])
    for e in out:
        ask.progress(f"      {e['effect']:<31} {e['shrink_pct']:+.1f}% ({e['gain_pts']:+.1f} points over "
                     f"{e['effects'][0]}, evidence {e['evidence']:+.1f}, information criterion "
                     f"{e['delta_bic']:+.1f}): " + ("kept" if e["kept"] else "not kept: " + "; ".join(e["why_not"])))
    return out, kept, pairs.ranked_second(out, kept, ranking[0]["effect"])

"""The diagnosis, start to end: where the gap lies, which effect, how far it shrinks."""
import tempfile
import time

import numpy as np

from . import calibrate
from . import confidence
from . import design
from . import effects as fx
from . import fit
from . import pairs
from . import separability
from . import gap
from . import phases as ph

# A candidate must shrink the held-out gap by at least this much to be named;
# otherwise the answer is `none` (noise and parameter drift stay below it).
THRESHOLD_PCT = 15.0


def _labels(run):
    return ph.split(run.t_s, run.signals["height_m"], run.load_n)


def where_table(problem, runs):
    """Nominal simulation of each run, phase tables and the ranked places of the gap."""
    tables = []
    traces = []
    per_run = []
    for run in runs:
        tr = problem.simulate(run, None, {})
        labels = _labels(run)
        rows = gap.phase_table(run, tr, labels)
        tables.append(rows)
        traces.append(tr)
        band = gap.band_of(problem.config_of(run))
        ev_real = gap.event_figures(run.t_s, run.signals, run.load_n, band)
        ev_sim = gap.event_figures(tr.t_s, tr.signals, run.load_n, band)
        per_run.append({"run": run.name, "mode": fit.choose_mode(run, problem.mode),
                        "phases": ph.spans(run.t_s, labels), "table": rows,
                        "events_real": ev_real, "events_nominal": ev_sim,
                        "events_difference": gap.event_differences(ev_real, ev_sim)})
    return {"ranked": gap.rank_places(tables), "runs": per_run}, traces


def before_after(problem, runs, nominal, augmented):
    """Held-out gaps overall and per phase, nominal vs augmented, and the shrink."""
    labels = [_labels(r) for r in runs]
    out = {"overall": {"before": gap.gap_over_runs(runs, nominal),
                       "after": gap.gap_over_runs(runs, augmented)}}
    per_phase = {}
    for p in ph.PHASES:
        masks = [lab == p for lab in labels]
        if not any(m.any() for m in masks):
            continue
        b = gap.gap_over_runs(runs, nominal, masks)
        a = gap.gap_over_runs(runs, augmented, masks)
        per_phase[p] = {"before": b, "after": a, "shrink_pct": shrink(b["normalised"], a["normalised"])}
    out["per_phase"] = per_phase
    ev = []
    for r, n, a in zip(runs, nominal, augmented):
        band = gap.band_of(problem.config_of(r))
        e_real = gap.event_figures(r.t_s, r.signals, r.load_n, band)
        ev.append({"run": r.name, "real": e_real,
                   "nominal": gap.event_figures(n.t_s, n.signals, r.load_n, band),
                   "augmented": gap.event_figures(a.t_s, a.signals, r.load_n, band)})
    out["events"] = ev
    return out


def _phase_energy(runs, traces, labels):
    """Per phase: summed normalised squared residual over runs."""
    out = {}
    for run, tr, lab in zip(runs, traces, labels):
        for sig, r in gap.residuals(run, tr).items():
            e = np.where(np.isfinite(r), (r / gap.SCALES[sig]) ** 2, 0.0)
            for p in ph.PHASES:
                out[p] = out.get(p, 0.0) + float(e[lab == p].sum())
    return out


def signatures(runs, problem, nominal, ranking):
    """Residual signature of each fitted candidate against the phase table (held-out):
    per-phase shrink, and how well the phases it fixes match where the gap lies
    (cosine of the nominal per-phase energy and the candidate's per-phase reduction)."""
    labels = [_labels(r) for r in runs]
    e_nom = _phase_energy(runs, nominal, labels)
    phases = [p for p in ph.PHASES if e_nom.get(p, 0.0) > 0.0]
    v_nom = np.array([e_nom[p] for p in phases])
    for entry in ranking:
        params = {k: v["value"] for k, v in entry["params"].items()}
        aug = [problem.best_start(r, entry["effect"], params)[0] for r in runs]
        e_aug = _phase_energy(runs, aug, labels)
        entry["per_phase_shrink_pct"] = {p: shrink(np.sqrt(e_nom[p]), np.sqrt(e_aug.get(p, 0.0)))
                                         for p in phases}
        red = np.array([e_nom[p] - e_aug.get(p, 0.0) for p in phases])
        den = np.linalg.norm(v_nom) * np.linalg.norm(red)
        entry["signature_match"] = float(v_nom @ red / den) if den > 0 else 0.0


# Perturbations far below the published resolution (0.01 in, 1 psi): 10-40 um of
# height and 50-200 Pa of pressure reading. The shrink they give by chance is
# what an on-off loop's event figures move by for no physical reason.
JITTERS = [(h, p) for h in (-40e-6, -10e-6, 10e-6, 40e-6) for p in (-200.0, 50.0)]


# Traces: a named effect must beat the floor by this many points.
FLOOR_MARGIN_PTS = 10.0


def sensitivity_floor(problem, nominal_gap, jitters=JITTERS):
    """Largest held-out shrink a physically meaningless jitter achieves."""
    best = 0.0
    for h, p in jitters:
        g = problem.gap("sensor_lag", {"h_offset_m": h, "p_offset_pa": p})
        best = max(best, shrink(nominal_gap, g))
    return best


shrink = gap.shrink


# Which phase each thesis event figure belongs to (for the `where` table of a features run).
FEATURE_PHASE = {
    "height_before_step_m": "steady", "lowest_height_m": "drop", "p2_drop_stop_pa": "drop",
    "time_stuck_bottom_s": "stuck_low", "p2_breakaway_pa": "stuck_low",
    "time_return_after_step_s": "climb", "p2_after_climb_pa": "settle",
    "highest_height_m": "jump", "p2_jump_pa": "jump", "time_stuck_top_s": "stuck_high",
    "p2_start_down_pa": "stuck_high", "time_return_after_removal_s": "return",
}


def _is_features(runs):
    return any(hasattr(r, "features") for r in runs)


def feature_table(run, trace):
    """Published figure vs simulated, difference in SI and in resolution units."""
    from .features import FEATURE_SCALE, KIND
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


def feature_before_after(problem, runs, nominal, augmented):
    from . import fit
    out = {"overall": {"before": {"normalised": fit.cost_to_gap(
                           np.concatenate([fit.run_residual(r, t) for r, t in zip(runs, nominal)]), len(runs))},
                       "after": {"normalised": fit.cost_to_gap(
                           np.concatenate([fit.run_residual(r, t) for r, t in zip(runs, augmented)]), len(runs))}},
           "per_phase": {}, "events": []}
    for r, n, a in zip(runs, nominal, augmented):
        out["events"].append({"run": r.name, "real": r.features, "nominal": r.figures(n),
                              "augmented": r.figures(a)})
    return out


def _params_of(entry):
    return {k: v["value"] for k, v in entry["params"].items()}


def lookalike_step(problem, ranking, threshold, named, progress, design_pair=None):
    """Separability of the leading candidates, and for a look-alike pair (or the
    pair asked for) the experiment that separates them best."""
    out = {"lookalikes": None, "experiment": None}
    if named:
        lk = separability.lookalikes(problem, ranking, threshold)
        out["lookalikes"] = lk
        for t in lk["tests"]:
            a, b = t["effects"]
            progress(f"      {a} vs {b}: {b} refitted on {a}'s simulated runs leaves {t['b_on_a_gap']:.3f} "
                     f"({a}'s own gap {t['a_own_gap']:.3f}), the other way {t['a_on_b_gap']:.3f} "
                     f"({t['b_own_gap']:.3f}): " + ("cannot be told apart" if t["cannot_tell_apart"]
                                                     else "told apart"))
    pair = design_pair or ((out["lookalikes"] or {}).get("group") or [])[:2]
    if len(pair) == 2:
        out["experiment"] = _experiment(problem, ranking, pair, progress)
    return out


def _fit_pairs(spec, config, calib, holdout, mode, jobs, fit_opts, plan, ranking, nominal_gaps, progress,
               screen):
    """Fits the planned pairs and returns ({name: fit result}, [pair entries])."""
    def on_pair(name, r):
        progress(f"      {name:<31} held-out gap {r['holdout_gap']:.3f} "
                 f"({shrink(nominal_gaps[1], r['holdout_gap']):+.1f}%) in {r['seconds']:.1f} s")

    res = fit.fit_pairs(spec, config, calib, holdout, plan, mode, jobs, on_pair, fit_opts, screen)
    by = {r["effect"]: r for r in ranking}
    return res, [pairs.entry(n, res[n], by, (len(calib), len(holdout)), shrink, *nominal_gaps, screen)
                 for n in plan]


def pair_step(spec, config, calib, holdout, mode, jobs, fit_opts, ranking, fits, threshold, nominal_gaps,
              progress, gate=0.0):
    """Pairs on top of the leader: a screening fit of each to rank the second
    effect, full joint fits of the best to judge (pairs.py). Returns
    (pair entries ranked by evidence, the kept one or None, the ranked second or None)."""
    screen = pairs.screen_plan(ranking, fits)
    if not screen:
        return [], None, None
    progress(f"      pairs on top of {ranking[0]['effect']}: screening {len(screen)}")
    res, screened = _fit_pairs(spec, config, calib, holdout, mode, jobs, fit_opts, screen, ranking,
                               nominal_gaps, progress, True)
    full = pairs.plan(ranking, screened, res)
    entries = {e["effect"]: e for e in screened}
    if full:
        progress(f"      fitting {len(full)} of them jointly in full")
        entries.update({e["effect"]: e for e in _fit_pairs(spec, config, calib, holdout, mode, jobs, fit_opts,
                                                            full, ranking, nominal_gaps, progress, False)[1]})
    by = {r["effect"]: r for r in ranking}
    kept = pairs.judge([entries[n] for n in full], by, threshold, nominal_gaps[1] - gate)
    out = sorted(entries.values(), key=lambda e: e["evidence"])
    for e in out:
        progress(f"      {e['effect']:<31} {e['shrink_pct']:+.1f}% ({e['gain_pts']:+.1f} points over the leader, "
                 f"evidence {e['evidence']:+.1f}, information criterion {e['delta_bic']:+.1f}): "
                 + ("kept" if e["kept"] else "not kept: " + "; ".join(e["why_not"])))
    return out, kept, pairs.ranked_second(out, kept)


def _where_step(cal_problem, hold_problem, calib, holdout, features, progress):
    """[1] where the gap lies, with the user's config as given."""
    progress(f"[1/4] where the gap lies: nominal simulation of {len(calib) + len(holdout)} run(s)")
    if features:
        where = feature_where(cal_problem, list(calib) + list(holdout))
    else:
        where, _ = where_table(cal_problem, list(calib) + list(holdout))
    for w in where["ranked"][:3]:
        if features:
            if w["difference"] is None:
                progress(f"      #{w['rank']} {w['run']}: {w['figure']} not produced by the simulation")
            else:
                progress(f"      #{w['rank']} {w['run']}: {w['figure']} off by {w['difference']:+.4g} (SI), "
                         f"{w['normalised']:+.1f} x its published resolution")
            continue
        progress(f"      #{w['rank']} {w['phase']:<10} {w['signal']:<6} bias {w['bias']:+.2f} {w['unit']}, "
                 f"RMS {w['rms']:.2f} {w['unit']} ({w['share_pct']:.0f}% of the gap)")
    return where


def _unexplained_step(hold_problem, holdout, ranking, kept, cal_gap, noise, threshold, progress):
    """confidence.unexplained on the best single or kept pair, with where the calibrated
    model's held-out residual lies per phase."""
    lead = dict(ranking[0])
    if kept and kept["shrink_pct"] > lead["shrink_pct"]:
        lead = {"effect": kept["effect"], "shrink_pct": kept["shrink_pct"]}
    cal_nominal = [hold_problem.best_start(r, None, {})[0] for r in holdout]
    per_phase = before_after(hold_problem, holdout, cal_nominal, cal_nominal)["per_phase"]
    per_phase = {p: {"before": v["before"]["normalised"]} for p, v in per_phase.items()}
    finding = confidence.unexplained([lead], cal_gap, noise, per_phase, threshold)
    if finding:
        progress(f"      not explained by any candidate: {finding['why']}; the residual lies in "
                 + ", ".join(f"{w['phase']} ({w['gap']:.2f})" for w in finding["where"]))
    return finding


def _experiment(problem, ranking, pair, progress):
    """The experiment that best separates two candidates the verdict cannot (design.py)."""
    by = {r["effect"]: r for r in ranking}
    a, b = by[pair[0]], by[pair[1]]
    exp = design.propose(problem, (a["effect"], _params_of(a)), (b["effect"], _params_of(b)))
    best = exp["ranked"][0]
    progress(f"      proposed experiment to tell {a['effect']} from {b['effect']}: {best['schedule']} "
             f"(predicted difference {best['separation_noise_units']:.1f} x sensor noise)")
    return exp


def _rival_experiment(sim, config, calib, cal_config, as_given, rival, progress):
    """The experiment that best tells the calibrated config from the rival effect on
    the config as given (design.py, each model with its own config)."""
    by = {r["effect"]: r for r in as_given}
    fx_side = (rival["effect"], _params_of(by[rival["effect"]]))
    exp = design.propose(fit.Problem(sim, config, calib), fx_side, (None, {}, cal_config, "calibration"))
    progress(f"      proposed experiment to tell the calibration from {rival['effect']}: "
             f"{exp['ranked'][0]['schedule']}")
    return exp


def _threshold(hold_problem, nominal_hold_gap, features):
    """(sensitivity floor, the shrink an explanation must reach on the held-out runs)."""
    if features:
        floor = sensitivity_floor(hold_problem, nominal_hold_gap)
        return floor, max(THRESHOLD_PCT, floor)
    floor = sensitivity_floor(hold_problem, nominal_hold_gap, hold_problem.start_shifts)
    return floor, max(THRESHOLD_PCT, floor + FLOOR_MARGIN_PTS)


def _calibration_step(sim, config, calib, holdout, mode, folder, threshold, progress):
    """[2] calibrate before blaming: (report or None, the config the effects are fitted on,
    the runs: those with a config of their own pointed at its calibrated version)."""
    from .cplant import config_path
    if not calibrate.supported(sim):
        progress("[2/4] calibration: not with this simulator; the config as given")
        return None, config, calib, holdout
    progress("[2/4] calibrating the config's nominal parameters before blaming an effect")
    rep = calibrate.calibrate(sim, config_path(config), calib, holdout, mode, folder, threshold, progress)
    calib, holdout = rep.pop("runs")
    return rep, rep.pop("config_file"), calib, holdout


# The calibration stands against the best effect (fitted alone on the config as given)
# only when it leaves a held-out gap smaller by this share of the effect's (and by the
# noise gate). Within this share the two explain the held-out runs alike: the effect is
# named, the calibration recorded as its look-alike (`rival`), and the verdict's
# confidence says so with the experiment that would tell them apart.
CALIBRATION_FIRST_PCT = 10.0


def _effect_first(calibration, best, gate, progress):
    """Whether the gap is the leading effect's rather than mis-set nominal values.
    Both were fitted on the calibration runs (the effect on the config as given) and
    are judged on held-out runs neither saw. Returns False when the calibration is
    clearly better: it stands, and an effect must explain what it leaves (_joint_step).
    Otherwise True: the calibration, which bends nominal values to mimic the effect,
    is not kept (recorded as the effect's `rival` when the two are alike)."""
    g_cal, g_fx = calibration["holdout_gap"]["after"], best["holdout_gap"]
    share = CALIBRATION_FIRST_PCT / 100.0
    if g_cal <= (1.0 - share) * g_fx and g_fx - g_cal >= gate:
        return False
    alike = g_fx >= (1.0 - share) * g_cal and calibration["moved"]
    if alike:
        calibration["rival"] = {"effect": best["effect"], "moved": list(calibration["moved"]),
                                "effect_gap": g_fx, "calibration_gap": g_cal}
    calibration.update(kept=False, moved=[], superseded_by=best["effect"],
                       why=calibration["why"].replace(", kept", "") +
                       f"; {best['effect']} alone leaves {g_fx:.3f}: "
                       + ("alike; the effect is named, the calibration is its look-alike" if alike else
                          "the effect explains the held-out runs better; calibration not kept"))
    for p in calibration["parameters"]:
        p["moved"] = False
    calibration["ini"] = None
    progress(f"      {best['effect']} leaves a held-out gap of {g_fx:.3f}, calibration {g_cal:.3f}: "
             + ("alike" if alike else "the effect explains it better") + "; calibration not kept")
    return True


def _settle_calibration(sim, calibration, handles, top, u_top, named, holdout, mode):
    """On the calibration path: the config the verdict stands on (the leading joint
    fit's when its effect is named, else the calibration's) and what moved in it.
    Returns the held-out problem on that config."""
    cal, hold, u, chosen = handles
    v = u_top if named else u
    if named:
        vals = cal.space.values(v)
        moved = [p["name"] for j, p in enumerate(calibration["parameters"]) if j in chosen and
                 abs(vals[j] / p["config"] - 1.0) >= calibrate.MATERIAL_REL]
        calibration.update(with_effect={"effect": top["effect"],
                                        "values": {p["name"]: float(vals[j])
                                                   for j, p in enumerate(calibration["parameters"])}},
                           moved=moved, kept=bool(moved))
        for j, p in enumerate(calibration["parameters"]):
            p["moved"] = p["name"] in moved
            # the values fitted with the effect are the model's; the calibration alone's stay beside them
            if j in chosen:
                p.update(value_alone=p["value"], change_pct_alone=p["change_pct"], value=float(vals[j]),
                         change_pct=(float(vals[j]) / p["config"] - 1.0) * 100.0)
        calibration["ini"] = calibrate.ini_text(cal.space.config_file, cal.space.name, cal.space.params, vals,
                                                [f"fitted with {top['effect']}" for _ in cal.space.params]) \
            if moved else None
    return fit.Problem(sim, cal.config(v), holdout, mode, fit.start_shifts(holdout))


def model_of(config, calibration, handles, v, entry):
    """The model the verdict's held-out figures were simulated with, for --write-config:
    the config as given, the calibrated values (v: the vector the final figures used,
    None off the calibration path) and the named entry's effect values, each with where
    it came from. Values are the very floats the simulations had."""
    from .cplant import config_path
    keys = []
    if v is not None:
        cal = handles[0]
        table = {p["name"]: p for p in calibration["parameters"]}
        for n, val in zip(cal.space.params, cal.space.values(v)):
            p = table.get(n.name, {})
            keys.append({"section": n.section, "key": n.key, "name": n.name, "value": float(val),
                         "config": p.get("config"), "interval": p.get("interval"),
                         "chosen": bool(p.get("chosen")), "moved": bool(p.get("moved"))})
    effects = {}
    for e in fx.parts(entry["effect"]) if entry else ():
        effects[e] = {q.name: {"value": float(entry["params"][q.name]["value"]),
                               "interval": entry["params"][q.name].get("interval")} for q in fx.get(e).params}
    return {"config": config_path(config), "keys": keys, "effects": effects}


JOINT_CANDIDATES = 2   # the effects (best alone on the config as given) fitted with the calibration


def _joint_step(handles, as_given, fits, gaps, progress):
    """The calibration path: the best effects alone, refitted together with the
    calibration's chosen values (calibrate.joint_fit), scored against the calibrated
    model's held-out gap; the other candidates keep their scores alone. Returns (the
    ranking over the calibrated model, the config of the leading joint fit or of the
    calibration)."""
    cal, hold, u, chosen = handles
    ranking, configs = [], {}
    for r in as_given:
        e = dict(r, shrink_pct=shrink(gaps[1], r["holdout_gap"]), joint=False)
        ranking.append(e)
    for r in sorted(as_given, key=lambda x: x["holdout_gap"])[:JOINT_CANDIDATES]:
        j = calibrate.joint_fit(cal, hold, chosen, fx.get(r["effect"]), fits[r["effect"]]["unit"])
        e = next(x for x in ranking if x["effect"] == r["effect"])
        configs[r["effect"]] = j["u"]
        e.update(holdout_gap=j["holdout_gap"], calibration_gap=j["calibration_gap"], joint=True,
                 shrink_pct=shrink(gaps[1], j["holdout_gap"]),
                 params={k: dict(v, value=j["params"][k]) for k, v in r["params"].items()})
        progress(f"      {r['effect']:<15} with the calibration: held-out gap {j['holdout_gap']:.3f} "
                 f"(calibrated {gaps[1]:.3f}, {e['shrink_pct']:+.1f}%)")
    ranking.sort(key=lambda x: -x["shrink_pct"])
    for i, r in enumerate(ranking, 1):
        r["rank"] = i
    top = ranking[0]["effect"]
    return ranking, configs.get(top, u)


def _rank_fits(candidates, fits, nominal_cal_gap, nominal_hold_gap):
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


def _effects_step(spec, config, calib, holdout, mode, candidates, jobs, fit_opts, hold_problem, gaps, progress):
    """[3] every candidate fitted on the calibration runs (on top of the calibrated
    config), scored on the held-out runs; ranked by held-out shrink."""
    nominal_cal_gap, nominal_hold_gap = gaps
    progress(f"[3/4] fitting {len(candidates)} candidate effect(s) on {len(calib)} run(s), "
             f"scoring on {len(holdout)} held-out run(s)")
    done = [0]

    def on_fit(name, r):
        done[0] += 1
        progress(f"      {done[0]}/{len(candidates)} {name:<15} held-out gap {r['holdout_gap']:.3f} "
                 f"(nominal {nominal_hold_gap:.3f}, {shrink(nominal_hold_gap, r['holdout_gap']):+.1f}%) "
                 f"in {r['seconds']:.1f} s")

    fits = fit.fit_all(spec, config, calib, holdout, mode, candidates, jobs, on_fit, fit_opts)
    ranking = _rank_fits(candidates, fits, nominal_cal_gap, nominal_hold_gap)
    if not _is_features(holdout):
        signatures(holdout, hold_problem, [hold_problem.best_start(r, None, {})[0] for r in holdout], ranking)
    ranking.sort(key=lambda x: -x["shrink_pct"])
    for i, r in enumerate(ranking, 1):
        r["rank"] = i
    return ranking, fits


def _confidence_step(sim, config, calib, cal_problem, cal_work, calibration, as_given, ranking, effects, cal_gap,
                     noise, look, finding, features, design_pair, progress):
    """How sure the verdict is (confidence.py), and the experiment that would separate
    what it cannot: the calibration from its rival effect, or two effects. Returns
    (look-alike step, with its experiment; confidence)."""
    rival = (calibration or {}).get("rival")
    sure = confidence.assess(effects, ranking, cal_gap, noise, look["lookalikes"] and look["lookalikes"]["group"],
                             look["experiment"], finding, rival)
    if not features and rival and not look["experiment"] and not design_pair:
        look = dict(look, experiment=_rival_experiment(sim, config, calib, cal_work, as_given, rival, progress))
        sure["experiment"] = look["experiment"]["ranked"][0]["schedule"]
    designable = [e for e in sure["set"] if e in fx.NAMES]     # effects, not "calibration: ..."
    if not features and effects and len(designable) >= 2 and not look["experiment"]:
        look = dict(look, experiment=_experiment(cal_problem, ranking, designable[:2], progress))
        sure["experiment"] = look["experiment"]["ranked"][0]["schedule"] if look["experiment"] else None
    progress(f"      confidence: {sure['level']}"
             + (f" (right {100 * sure['probability']['p']:.0f}% of the time on truths written apart)"
                if sure["probability"] else "") + f": {sure['why']}"
             + (f"; {'cannot separate' if effects or rival else 'nearest'}: {', '.join(sure['set'])}"
                if sure["level"] != "sure" and sure["set"] else ""))
    return look, sure


def _before_after_step(hold_problem, holdout, user_nominal_hold, top, features):
    """[4] the held-out runs under the final model (top: the named entry, or None) against
    the config as given. Returns (augmented traces, the before/after tables)."""
    if top:
        aug_hold = [hold_problem.best_start(r, top["effect"], _params_of(top))[0] for r in holdout]
    else:
        aug_hold = [hold_problem.best_start(r, None, {})[0] for r in holdout]
    if features:
        return aug_hold, feature_before_after(hold_problem, holdout, user_nominal_hold, aug_hold)
    return aug_hold, before_after(hold_problem, holdout, user_nominal_hold, aug_hold)


def _result(config, mode, calib, holdout, threshold, floor, where, calibration, sure, finding, noise, ranking,
            winner, effects, pairs_, look, ba, gaps, named, t0):
    """diagnosis.json's content."""
    best = ranking[0]
    runner = ranking[1] if len(ranking) > 1 else None
    pair_list, kept, second = pairs_
    return {
        "config": config,
        "mode": mode,
        "calibration_runs": [r.name for r in calib],
        "holdout_runs": [r.name for r in holdout],
        "threshold_pct": threshold,
        "sensitivity_floor_pct": floor,
        "where": where,
        # the nominal parameters fitted before any effect (calibrate.py); None: not done
        "calibration": calibration,
        # how sure, and what no candidate explains (confidence.py)
        "confidence": sure,
        "unexplained": finding,
        "noise_gap": noise,
        "ranking": ranking,
        "effect": winner,
        # the ranked combination: the leader, and a second effect when a pair is kept (pairs.py)
        "effects": effects,
        "pairs": pair_list,
        # second place of the ranked combination: what best explains what the leader leaves
        # (pairs.py; named only when kept), else, without pairs, the runner-up single
        "second": second or ({"effect": runner["effect"], "pair": None, "kept": False} if runner else None),
        "ranked_combination": [best["effect"]] + ([(second or runner)["effect"]] if (second or runner) else []),
        "margin_pct": (best["shrink_pct"] - runner["shrink_pct"]) if runner else None,
        "runner_up": runner["effect"] if runner else None,
        # look-alikes: the candidates these logs cannot tell apart (the winner first), with evidence
        "cannot_tell_apart": (look["lookalikes"] or {}).get("group", []),
        "separability": (look["lookalikes"] or {}).get("tests", []),
        "experiment": look["experiment"],
        "gap_before": ba["overall"]["before"],
        "gap_after": ba["overall"]["after"],
        # the config as given -> the calibrated config with the named effect(s)
        "shrink_pct": shrink(ba["overall"]["before"]["normalised"], ba["overall"]["after"]["normalised"]),
        # the named effect(s) alone, on top of the calibrated config
        "effect_shrink_pct": (shrink(gaps[1], (kept or best)["holdout_gap"]) if named else 0.0),
        "per_phase": ba["per_phase"],
        "events": ba["events"],
        "seconds": time.perf_counter() - t0,
    }


def diagnose(spec, sim, config, calib, holdout, mode="auto", candidates=None, jobs=None,
             progress=print, fit_opts=None, design_pair=None):
    """Returns (result dict for diagnosis.json, traces for the report)."""
    with tempfile.TemporaryDirectory(prefix="leveler-calibration-") as folder:
        return _diagnose(spec, sim, config, calib, holdout, mode, candidates or fx.NAMES, jobs, progress,
                         fit_opts, design_pair, folder)


def _diagnose(spec, sim, config, calib, holdout, mode, candidates, jobs, progress, fit_opts, design_pair, folder):
    t0 = time.perf_counter()
    features = _is_features(list(calib) + list(holdout))
    user_hold = fit.Problem(sim, config, holdout, mode, fit.start_shifts(holdout))
    where = _where_step(fit.Problem(sim, config, calib, mode), user_hold, calib, holdout, features, progress)
    user_nominal_hold = [user_hold.best_start(r, None, {})[0] for r in holdout]
    floor, threshold = _threshold(user_hold, user_hold.gap(None, {}), features)
    calibration, cal_work, cal_runs, cal_hold = _calibration_step(sim, config, calib, holdout, mode, folder,
                                                                  threshold, progress)
    work = config
    cal_problem = fit.Problem(sim, config, calib, mode)
    gaps = (cal_problem.gap(None, {}), user_hold.gap(None, {}))
    hold_problem = user_hold
    ranking, fits = _effects_step(spec, config, calib, holdout, mode, candidates, jobs, fit_opts, user_hold, gaps,
                                  progress)
    as_given = ranking
    noise = 0.0 if features else fit.noise_gap(holdout)     # the logs' own, the same before and after
    gate = fit.NOISE_GAIN * noise
    if calibration:     # the candidates on the config as given, beside the calibration's figures
        calibration["effects_as_given"] = [{k: r[k] for k in ("effect", "holdout_gap", "shrink_pct")}
                                           for r in ranking]
    handles = calibration.pop("handles") if calibration else None
    calibrated_path = False
    if calibration and calibration["kept"] and not _effect_first(calibration, ranking[0], gate, progress):
        # the calibration stands: an effect must explain what it leaves, fitted with it
        calibrated_path = True
        calib, holdout = cal_runs, cal_hold
        gaps = (calibration["calibration_gap"]["after"], calibration["holdout_gap"]["after"])
        ranking, u_top = _joint_step(handles, ranking, fits, gaps, progress)
        work = handles[0].config(u_top)
        cal_problem = fit.Problem(sim, work, calib, mode)
        # the threshold and what is left unexplained: against the calibrated model itself
        hold_problem = fit.Problem(sim, handles[0].config(handles[2]), holdout, mode, fit.start_shifts(holdout))
        floor, threshold = _threshold(hold_problem, gaps[1], features)
    best = ranking[0]
    runner = ranking[1] if len(ranking) > 1 else None
    progress(f"      sensitivity floor of the held-out {'figures' if features else 'runs'}: {floor:.1f}% "
             f"(threshold {threshold:.1f}%)")
    named_single = best["shrink_pct"] >= threshold and gaps[1] - best["holdout_gap"] >= gate
    if best["shrink_pct"] >= threshold and not named_single:
        progress(f"      {best['effect']} lowers the held-out gap by {gaps[1] - best['holdout_gap']:.3f}, less than "
                 f"half the gap of the logs' own noise ({gate:.3f}): no evidence of an effect")
    pair_list, kept, second = ([], None, None) if features or calibrated_path else pair_step(
        spec, work, calib, holdout, mode, jobs, fit_opts, ranking, fits, threshold, gaps, progress, gate)
    named = named_single or kept is not None
    finding = None if features else _unexplained_step(hold_problem, holdout, ranking, kept, gaps[1], noise,
                                                      threshold, progress)
    named = named and finding is None
    final_v = None
    if calibrated_path:
        hold_problem = _settle_calibration(sim, calibration, handles, ranking[0], u_top, named, holdout, mode)
        final_v = u_top if named else handles[2]
    winner = best["effect"] if named else ("not explained" if finding else "none")
    effects = kept["effects"] if kept and named else ([winner] if named else [])
    look = lookalike_step(cal_problem, ranking, threshold, named and named_single and not features, progress,
                          design_pair)
    look, sure = _confidence_step(sim, config, calib, cal_problem, cal_work, calibration, as_given, ranking,
                                  effects, gaps[1], noise, look, finding, features, design_pair, progress)
    progress(f"[4/4] before/after on held-out runs (the config as given against "
             f"{'the calibrated config' if calibration and calibration['kept'] else 'the config'}"
             f"{' + ' + fx.combine(effects) if named else ', no effect'})")
    aug_hold, ba = _before_after_step(hold_problem, holdout, user_nominal_hold, (kept or best) if named else None,
                                      features)
    result = _result(config, mode, calib, holdout, threshold, floor, where, calibration, sure, finding, noise,
                     ranking, winner, effects, (pair_list, kept, second), look, ba, gaps, named, t0)
    # what the after-figures ran on (--write-config): exact values, not the report's digits
    result["model"] = model_of(config, calibration, handles, final_v, (kept or best) if named else None)
    traces = {"holdout": holdout, "nominal": user_nominal_hold, "augmented": aug_hold}
    return result, traces

"""Calibrate before blaming, in the diagnosis: the nominal parameters fitted first
(calibrate.py); whether they or the leading effect explain the held-out runs better;
on the calibration path, the best effects refitted together with them."""
import os
from dataclasses import replace

from . import calibrate
from . import candidates
from . import effects as fx
from . import fit
from . import shut_spring
from .cplant import config_path
from .confidence import EXPLAINS_PCT
from .gap import shrink

# The calibration and the best effect (fitted alone on the config as given) explain the
# held-out runs alike when their held-out gaps differ by less than this share (or than
# the noise gate): the one with the smaller gap stands (the calibration on a tie), the
# other is recorded as its look-alike (`rival`), and the verdict's confidence says so
# with the experiment that would tell them apart.
CALIBRATION_FIRST_PCT = 100.0 * calibrate.ALIKE_SHARE

JOINT_CANDIDATES = 2   # the effects (best alone on the config as given) fitted with the calibration


def calibration_step(ask, calib, holdout, folder, threshold):
    """[2] calibrate before blaming: (report or None, the config the calibration wrote,
    the runs: those with a config of their own pointed at its calibrated version)."""
    if not calibrate.supported(ask.sim):
        ask.progress("[2/4] calibration: not with this simulator; the config as given")
        return None, ask.config, (calib, holdout)
    ask.progress("[2/4] calibrating the config's nominal parameters before blaming an effect")
    rep = calibrate.calibrate(ask.sim, config_path(ask.config), calib, holdout, ask.mode, folder, threshold,
                              ask.progress, jobs=_jobs(ask))
    runs = rep.pop("runs")
    return rep, rep.pop("config_file"), runs


def _jobs(ask):
    """Processes for the calibration's trials: the asked number, else up to two."""
    return ask.jobs or min(os.cpu_count() or 1, 2)


def under_effect(ask, best, first, calib, holdout, folder, threshold, why=None):
    """The leading effect (fitted on the config as given) leaves the held-out runs far
    from explained: a mis-set value beside it? The values are calibrated again with
    the effect in the model (its fit as given, held); kept when they close half of
    what the effect leaves (confidence.EXPLAINS_PCT: less explains nothing; an off-form
    effect's misfit is otherwise taken up by values that are not wrong) and more than
    the noise gate. The report then describes the values alone (gaps without the
    effect; `first`, the calibration without it, has them at the config's values), and
    the candidates are fitted with them (calibrated_basis). why: what the progress
    line says brought it here. Returns (report, config, runs) or None."""
    ask.progress(f"      {why or best['effect'] + ' leaves the held-out runs unexplained'}: the nominal values "
                 f"calibrated again with {best['effect']} in the model")
    rep = calibrate.calibrate(ask.sim, config_path(ask.config), calib, holdout, ask.mode, folder,
                              max(threshold, EXPLAINS_PCT), ask.progress, jobs=_jobs(ask),
                              effect=(best["effect"], candidates.values_of(best)))
    runs, config = rep.pop("runs"), rep.pop("config_file")
    if not (rep["kept"] and rep["moved"]):
        return None
    cal, hold, u, chosen = rep["handles"]
    cal0, hold0 = cal.without_effect(), hold.without_effect()
    rep.update(under_effect={"effect": best["effect"], "holdout_gap": rep["holdout_gap"]},
               calibration_gap={"before": first["calibration_gap"]["before"], "after": cal0.gap(u)},
               holdout_gap={"before": first["holdout_gap"]["before"], "after": hold0.gap(u)},
               handles=(cal0, hold0, u, chosen),
               why=f"calibrated with {best['effect']} in the model: " + rep["why"])
    rep["shrink_pct"] = shrink(rep["holdout_gap"]["before"], rep["holdout_gap"]["after"])
    rep["alone"] = {k: first[k] for k in ("why", "holdout_gap", "shrink_pct")}
    return rep, config, runs


def under_leak(ask, calibration, as_given, calib, holdout, folder, threshold, gate):
    """The calibration runs' shut stretches show air leaving the spring
    (shut_spring.leak_seen) and no effect as given is a leak: the values calibrated
    again with that leak in the model (under_effect). Returns (report, config, runs)
    when the model with it leaves a held-out gap below the calibration alone's and
    the leading effect's alone by more than the alike share and the noise gate;
    else None (the diagnosis goes on as without it)."""
    if not calibration or as_given[0]["effect"] == shut_spring.LEAK:
        return None
    seen = shut_spring.leak_seen(ask, calib)
    if not seen:
        return None
    area = seen["params"]["leak_area_m2"]
    entry = {"effect": shut_spring.LEAK, "params": {k: {"value": v} for k, v in seen["params"].items()}}
    again = under_effect(ask, entry, calibration, calib, holdout, folder, threshold,
                         why=f"the spring loses air with its valves shut ({'+'.join(f'{s:.1f}' for s in seen['seconds'])}"
                             f" s at the runs' starts: a leak of {area:.3g} m^2, gap there {seen['gap'][0]:.3f} -> "
                             f"{seen['gap'][1]:.3f})")
    if not again:
        return None
    g = again[0]["under_effect"]["holdout_gap"]["after"]
    g_cal = calibration["holdout_gap"]["after" if calibration["kept"] else "before"]
    rival = min(g_cal, as_given[0]["holdout_gap"])
    if not (g < (1.0 - calibrate.ALIKE_SHARE) * rival and rival - g >= gate):
        ask.progress(f"      with the leak the calibration leaves {g:.3f}, against {rival:.3f} without it: "
                     f"not better, the leak is left to the candidates")
        return None
    again[0]["shut_spring"] = seen
    return again


def beside_effects(calibration, ranking):
    """Records the candidates on the config as given beside the calibration's figures;
    returns the calibration's fitting handles (not written out), or None."""
    if not calibration:
        return None
    calibration["effects_as_given"] = [{k: r[k] for k in ("effect", "holdout_gap", "shrink_pct")}
                                       for r in ranking]
    return calibration.pop("handles")


def pinned(calibration):
    """The moved values the calibration left at the edge of the range a config may be
    wrong by (calibrate.NOMINALS' rel factors, chosen from the physics): a user who
    mis-set that value would have had to be wrong by more than the range allows. A
    physical limit (a discharge coefficient's cap of 1, the polytropic exponent's
    1.0 .. 1.4) is no such edge: a rig may sit on it."""
    rel = {n.name: n for n in calibrate.NOMINALS if n.rel}
    out = []
    for p in calibration["parameters"]:
        n = rel.get(p["name"])
        if not (n and p["moved"] and p["at_bound"]):
            continue
        lo, hi = p["range"]
        capped = n.cap is not None and hi >= n.cap and p["value"] > 0.5 * (lo + hi)
        if not capped:
            out.append(p["name"])
    return out


def effect_first(calibration, best, gate, progress):
    """Whether the gap is the leading effect's rather than mis-set nominal values.
    Both were fitted on the calibration runs (the effect on the config as given) and
    are judged on held-out runs neither saw; the better there stands. Returns False
    when the calibration leaves the smaller held-out gap: it stands, and an effect
    must explain what it leaves (calibrated_basis). Nominal values come first: when
    the two are alike (within CALIBRATION_FIRST_PCT, or closer than the noise gate)
    the calibration still stands, the effect recorded as its `rival`, unless it
    needed a value pinned at the edge of its range (pinned): then the effect is
    named. Otherwise True: the calibration, which bends nominal values to mimic the
    effect, is not kept (the effect's `rival` when the two are alike)."""
    g_cal, g_fx = calibration["holdout_gap"]["after"], best["holdout_gap"]
    share = CALIBRATION_FIRST_PCT / 100.0
    alike_gaps = g_cal > (1.0 - share) * g_fx or g_fx - g_cal < gate
    edge = pinned(calibration)
    if g_cal <= g_fx and alike_gaps and calibration["moved"] and edge:
        _record_rival(calibration, best["effect"], g_fx, g_cal)
        set_aside(calibration, best["effect"], g_fx,
                  f"alike, but the calibration needs {', '.join(edge)} at the edge of its range: the effect "
                  f"is named, the calibration is its look-alike", progress)
        return True
    if g_cal <= g_fx:
        if alike_gaps and calibration["moved"]:
            _record_rival(calibration, best["effect"], g_fx, g_cal)
            calibration["why"] += f"; {best['effect']} alone leaves {g_fx:.3f}: alike, the calibration stands"
        progress(f"      {best['effect']} leaves a held-out gap of {g_fx:.3f}, calibration {g_cal:.3f}: "
                 + ("alike; the calibration stands, the effect is its look-alike" if calibration.get("rival")
                    else "the calibration stands"))
        return False
    alike = g_fx >= (1.0 - share) * g_cal and calibration["moved"]
    if alike:
        _record_rival(calibration, best["effect"], g_fx, g_cal)
    set_aside(calibration, best["effect"], g_fx,
              "alike; the effect is named, the calibration is its look-alike" if alike else
              "the effect explains the held-out runs better; calibration not kept", progress)
    return True


def _record_rival(calibration, effect, g_fx, g_cal):
    """The effect and the calibration explain the held-out runs alike (effect_first)."""
    calibration["rival"] = {"effect": effect, "moved": list(calibration["moved"]),
                            "effect_gap": g_fx, "calibration_gap": g_cal}


def rival_outdone(calibration, top, gate, progress):
    """The calibration stood with a rival (an effect alone on the config as given that
    explains the held-out runs about as well as the calibration alone), and an effect
    is now named on top of the calibration (`top`, its ranking entry). The rival is a
    look-alike of the calibration alone, not of the model that stands: when that
    model's held-out gap is below the rival's by more than the alike share and the
    noise gate, the rival is no look-alike (kept as `rival_outdone`)."""
    rival = calibration.get("rival")
    if not rival or top is None:
        return
    g_top, g_fx = top["holdout_gap"], rival["effect_gap"]
    if g_top < (1.0 - CALIBRATION_FIRST_PCT / 100.0) * g_fx and g_fx - g_top >= gate:
        calibration["rival_outdone"] = dict(calibration.pop("rival"), model_gap=g_top, named=top["effect"])
        progress(f"      the calibration with {top['effect']} leaves a held-out gap of {g_top:.3f}, "
                 f"{rival['effect']} alone {g_fx:.3f}: no longer its look-alike")


def set_aside(calibration, effect, g_fx, why, progress):
    """The calibration is not kept: `effect` (one or a pair, "a+b") leaving the held-out
    gap g_fx is named instead; the report keeps the calibration's figures and says why."""
    calibration.update(kept=False, moved=[], superseded_by=effect,
                       why=calibration["why"].replace(", kept", "") + f"; {effect} leaves {g_fx:.3f}: {why}")
    for p in calibration["parameters"]:
        p["moved"] = False
    calibration["ini"] = None
    progress(f"      {effect} leaves a held-out gap of {g_fx:.3f}, calibration "
             f"{calibration['holdout_gap']['after']:.3f}: {why}")


def _joint_step(handles, as_given, fits, gaps, progress, resolution_s):
    """The best effects alone, refitted together with the calibration's chosen values
    (calibrate.joint_fit), scored against the calibrated model's held-out gap; the
    other candidates keep their scores alone (on_calibrated_model replaces them).
    Returns (the ranking over the calibrated model, {effect: vector of its joint fit})."""
    ranking, vectors = [], {}
    for r in as_given:
        e = dict(r, shrink_pct=shrink(gaps[1], r["holdout_gap"]), joint=False)
        # what a candidate made worse was measured on the config as given, not on this model
        e.pop("worsened_share", None)
        e.pop("worsened_phases", None)
        ranking.append(e)
    for r in sorted(as_given, key=lambda x: x["holdout_gap"])[:JOINT_CANDIDATES]:
        e = next(x for x in ranking if x["effect"] == r["effect"])
        vectors[r["effect"]] = _joint(handles, e, fits[r["effect"]]["unit"], gaps, progress,
                                      starts=(None, handles[2]))
    candidates.rank(ranking, resolution_s)
    return ranking, vectors


def _joint(handles, e, unit, gaps, progress, starts):
    """Ranking entry e refitted together with the calibration's chosen values, from
    its fit's unit vector and each of `starts` (vectors of values, None the config's);
    e is updated to the joint fit. Returns the joint fit's vector of values."""
    cal, hold, u, chosen = handles
    j = calibrate.joint_fit(cal, hold, chosen, fx.get(e["effect"]), unit, starts)
    e.update(holdout_gap=j["holdout_gap"], calibration_gap=j["calibration_gap"], joint=True,
             shrink_pct=shrink(gaps[1], j["holdout_gap"]),
             params={k: dict(v, value=j["params"][k]) for k, v in e["params"].items()})
    progress(f"      {e['effect']:<15} with the calibration: held-out gap {j['holdout_gap']:.3f} "
             f"(calibrated {gaps[1]:.3f}, {e['shrink_pct']:+.1f}%)")
    return j["u"]


def on_calibrated_model(ask, ranking, vectors, handles, runs, gaps, noise):
    """The candidates not fitted with the calibration, fitted alone on the calibrated
    model: an effect is named for what the calibration leaves, and one that did
    nothing on the config as given (where a mis-set value hid it) can explain that.
    The best of them that lowers the calibrated model's held-out gap is then fitted
    with the calibration's values (from theirs). Only when the calibrated model
    leaves more than the noise gate above the logs' noise (below it nothing can be
    named). Returns the ranking with their entries scored there (`on_calibrated`);
    vectors gains the joint fit's."""
    rest = [r["effect"] for r in ranking if not r.get("joint")]
    if not rest or gaps[1] - noise < fit.NOISE_GAIN * noise:
        return ranking
    calib, holdout = runs
    ask.progress(f"      {len(rest)} more candidate(s) fitted alone on the calibrated model")

    def on_fit(name, r):
        ask.progress(f"      {name:<15} on the calibrated model: held-out gap {r['holdout_gap']:.3f} "
                     f"(calibrated {gaps[1]:.3f}, {shrink(gaps[1], r['holdout_gap']):+.1f}%)")

    res = fit.fit_all(ask.spec, handles[0].config(handles[2]), calib, holdout, ask.mode, rest, ask.jobs, on_fit,
                      ask.fit_opts)
    fresh = {e["effect"]: dict(e, joint=False, on_calibrated=True)
             for e in candidates.scored(rest, res, *gaps)}
    best = min(fresh.values(), key=lambda e: e["holdout_gap"])
    if best["holdout_gap"] < gaps[1]:
        vectors[best["effect"]] = _joint(handles, best, res[best["effect"]]["unit"], gaps, ask.progress,
                                         starts=(handles[2],))
    out = [fresh.get(r["effect"], r) for r in ranking]
    candidates.rank(out, ask.resolution_s)
    return out


def calibrated_basis(ask, evidence, calibration, handles, runs, basis):
    """The calibration stands: the basis the candidates are judged on becomes the
    calibrated model (its runs, gaps, joint fits, the other candidates fitted on it);
    the threshold and what is left unexplained are measured against it."""
    calib, holdout = runs
    gaps = (calibration["calibration_gap"]["after"], calibration["holdout_gap"]["after"])
    ranking, vectors = _joint_step(handles, basis.ranking, basis.fits, gaps, ask.progress, ask.resolution_s)
    ranking = on_calibrated_model(ask, ranking, vectors, handles, runs, gaps, evidence.noise_gap(holdout))
    u_top = vectors.get(ranking[0]["effect"], handles[2])
    work = handles[0].config(u_top)
    cal_problem = fit.Problem(ask.sim, work, calib, ask.mode)
    hold_problem = fit.Problem(ask.sim, handles[0].config(handles[2]), holdout, ask.mode, fit.start_shifts(holdout))
    floor, threshold = evidence.threshold(hold_problem, gaps[1])
    return replace(basis, calib=calib, holdout=holdout, gaps=gaps, ranking=ranking, work=work,
                   cal_problem=cal_problem, hold_problem=hold_problem, floor=floor, threshold=threshold,
                   calibrated=True, u_top=u_top)


def settle(ask, calibration, handles, basis, named):
    """On the calibration path: the config the verdict stands on (the leading joint
    fit's when its effect is named, else the calibration's) and what moved in it.
    Returns (the held-out problem on that config, its vector)."""
    cal, hold, u, chosen = handles
    v = basis.u_top if named else u
    if named:
        _record_with_effect(calibration, cal, chosen, basis.ranking[0], cal.space.values(v))
    return fit.Problem(ask.sim, cal.config(v), basis.holdout, ask.mode, fit.start_shifts(basis.holdout)), v


def _record_with_effect(calibration, cal, chosen, top, vals):
    """The calibration's report once an effect is named with it: the values fitted with
    the effect are the model's; the calibration alone's stay beside them."""
    moved = [p["name"] for j, p in enumerate(calibration["parameters"]) if j in chosen and
             abs(vals[j] / p["config"] - 1.0) >= calibrate.MATERIAL_REL]
    calibration.update(with_effect={"effect": top["effect"],
                                    "values": {p["name"]: float(vals[j])
                                               for j, p in enumerate(calibration["parameters"])}},
                       moved=moved, kept=bool(moved))
    for j, p in enumerate(calibration["parameters"]):
        p["moved"] = p["name"] in moved
        if j in chosen:
            p.update(value_alone=p["value"], change_pct_alone=p["change_pct"], value=float(vals[j]),
                     change_pct=(float(vals[j]) / p["config"] - 1.0) * 100.0)
    calibration["ini"] = calibrate.ini_text(cal.space.config_file, cal.space.name, cal.space.params, vals,
                                            [f"fitted with {top['effect']}" for _ in cal.space.params]) \
        if moved else None

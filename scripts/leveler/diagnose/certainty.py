"""How sure the diagnosis's verdict is: the candidates these runs cannot tell apart
(separability.py), the confidence (confidence.py), and the experiment that would
separate what the verdict cannot (design.py)."""
from . import confidence
from . import design
from . import effects as fx
from . import fit
from . import separability
from .candidates import values_of
from .cplant import floor_above_noise


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


def _experiment(problem, ranking, pair, progress):
    """The experiment that best separates two candidates the verdict cannot, on which
    each of them also shows against no effect (design.py)."""
    by = {r["effect"]: r for r in ranking}
    a, b = by[pair[0]], by[pair[1]]
    exp = design.propose(problem, (a["effect"], values_of(a)), (b["effect"], values_of(b)),
                         base=(None, {}, problem.config, "none"))
    best = exp["ranked"][0]
    progress(f"      proposed experiment to tell {a['effect']} from {b['effect']}: {best['schedule']} "
             f"(predicted difference {best['separation_noise_units']:.1f} x sensor noise)")
    return exp


def _none_experiment(problem, hint, progress):
    """The experiment that best tells the model as it stands (the calibrated one when
    kept) from it with the hinted effect (confidence.hinted)."""
    exp = design.propose(problem, (hint["effect"], values_of(hint)), (None, {}, problem.config, "none"))
    progress(f"      proposed experiment to tell {hint['effect']} from none: {exp['ranked'][0]['schedule']}")
    return exp


def _rival_experiment(sim, config, calib, cal_config, as_given, rival, progress):
    """The experiment that best tells the calibrated config from the rival effect on
    the config as given (design.py, each model with its own config)."""
    by = {r["effect"]: r for r in as_given}
    fx_side = (rival["effect"], values_of(by[rival["effect"]]))
    exp = design.propose(fit.Problem(sim, config, calib), fx_side, (None, {}, cal_config, "calibration"))
    progress(f"      proposed experiment to tell the calibration from {rival['effect']}: "
             f"{exp['ranked'][0]['schedule']}")
    return exp


def alike_names(calibration):
    """The kept calibration's moved values and those alike to them (calibrate.alike_values),
    when there are alike ones; else []."""
    cal = calibration or {}
    if not cal.get("kept") or not cal.get("alike"):
        return []
    return list(dict.fromkeys(list(cal["moved"]) + [a["name"] for a in cal["alike"]]))


def moved_parts(calibration):
    """The kept calibration's moved values by part of the rig (config section): {section: [name, ...]}."""
    cal = calibration or {}
    out = {}
    for p in cal.get("parameters", []) if cal.get("kept") else []:
        if p["name"] in cal.get("moved", []):
            out.setdefault(p["section"], []).append(p["name"])
    return out


def confidence_step(ask, evidence, basis, verdict, look, calibration, cal_config, as_given, noise):
    """How sure the verdict is (confidence.py), and the experiment that would separate
    what it cannot: the calibration from its rival effect, or two effects. Returns
    (look-alike step, with its experiment; confidence)."""
    rival = (calibration or {}).get("rival")
    effects = verdict.effects
    sure = confidence.assess(effects, basis.ranking, basis.gaps[1], noise,
                             look["lookalikes"] and look["lookalikes"]["group"], look["experiment"],
                             verdict.finding, rival, alike_names(calibration), moved_parts(calibration),
                             basis.threshold, unmoved=bool(calibration and calibration.get("kept") and
                                                           not calibration.get("moved")),
                             resolved=not any(floor_above_noise(r) for r in basis.holdout))
    designs = evidence.designs_experiments
    if designs and sure["set"][1:] == ["none"] and not look["experiment"] and not ask.design_pair:
        hint = next(r for r in basis.ranking if r["effect"] == sure["set"][0])     # confidence.hinted
        look = dict(look, experiment=_none_experiment(basis.cal_problem, hint, ask.progress))
        sure["experiment"] = look["experiment"]["ranked"][0]["schedule"]
    if designs and rival and not look["experiment"] and not ask.design_pair:
        look = dict(look, experiment=_rival_experiment(ask.sim, ask.config, basis.calib, cal_config, as_given,
                                                       rival, ask.progress))
        sure["experiment"] = look["experiment"]["ranked"][0]["schedule"]
    designable = [e for e in sure["set"] if e in fx.NAMES]     # effects, not "calibration: ..."
    if designs and effects and len(designable) >= 2 and not look["experiment"]:
        look = dict(look, experiment=_experiment(basis.cal_problem, basis.ranking, designable[:2], ask.progress))
        sure["experiment"] = look["experiment"]["ranked"][0]["schedule"] if look["experiment"] else None
    ask.progress(f"      confidence: {sure['level']}"
                 + (f" (right {100 * sure['probability']['p']:.0f}% of the time on truths written apart)"
                    if sure["probability"] else "") + f": {sure['why']}"
                 + (f"; {'cannot separate' if effects or rival else 'nearest'}: {', '.join(sure['set'])}"
                    if sure["level"] != "sure" and sure["set"] else ""))
    return look, sure

"""The diagnosis, start to end: where the gap lies, calibrate before blaming, which
effect, how sure, how far the gap shrinks.

The steps are the same whatever the evidence; where run logs and published figures
differ, the evidence's strategy answers (evidence.py: evidence_runs.py,
evidence_figures.py). The steps: calibration_path.py, candidates.py, certainty.py;
what they hand each other: context.py; diagnosis.json: result.py."""
import tempfile
import time
from dataclasses import replace

from . import calibration_path
from . import candidates as cand
from . import certainty
from . import effects as fx
from . import fit
from . import pairs
from . import result as result_mod
from .confidence import leaves_much
from .context import Ask, Basis, Verdict
from .evidence_figures import PublishedFigures
from .evidence_runs import RunLogs
from .model import REPLAY


def evidence_of(runs):
    """The strategy for what was given: published figures (features.py) or run logs."""
    return PublishedFigures() if any(hasattr(r, "features") for r in runs) else RunLogs()


def diagnose(spec, sim, config, calib, holdout, mode="auto", candidates=None, jobs=None,
             progress=print, fit_opts=None, design_pair=None):
    """Returns (result dict for diagnosis.json, traces for the report)."""
    calib, holdout = placed(sim, config, calib, mode), placed(sim, config, holdout, mode)
    given = list(calib) + list(holdout)
    evidence = evidence_of(given)
    ask = Ask(spec, sim, config, mode, candidates or fx.NAMES, jobs, progress, fit_opts, design_pair,
              evidence.resolution_s(given))
    with tempfile.TemporaryDirectory(prefix="leveler-calibration-") as folder:
        return _diagnose(ask, evidence, calib, holdout, folder)


def placed(sim, config, runs, mode):
    """Coarse logs replayed open loop, with each switch placed within the samples
    that bracket it on the config as given (CPlant.placed, edges.py)."""
    if not hasattr(sim, "placed"):
        return list(runs)
    return [sim.placed(config, r) if getattr(r, "has_commands", False) and fit.choose_mode(r, mode) == REPLAY
            else r for r in runs]


def _diagnose(ask, evidence, calib, holdout, folder):
    t0 = time.perf_counter()
    user_hold = fit.Problem(ask.sim, ask.config, holdout, ask.mode, fit.start_shifts(holdout))
    where = _where_step(ask, evidence, calib, holdout)
    user_nominal_hold = [user_hold.best_start(r, None, {})[0] for r in holdout]
    floor, threshold = evidence.threshold(user_hold, user_hold.gap(None, {}))
    calibration, cal_config, cal_runs = calibration_path.calibration_step(ask, calib, holdout, folder, threshold)
    basis = _as_given(ask, evidence, calib, holdout, user_hold, floor, threshold)
    as_given = basis.ranking
    noise = evidence.noise_gap(holdout)     # the logs' own, the same before and after
    gate = fit.NOISE_GAIN * noise
    handles = calibration_path.beside_effects(calibration, as_given)
    given = basis
    # a leak seen with the valves shut: the values calibrated with it in the model
    again = calibration_path.under_leak(ask, calibration, as_given, calib, holdout, folder, threshold, gate)
    if again is None and calibration and calibration["kept"] and \
            not calibration_path.effect_first(calibration, as_given[0], gate, ask.progress):
        # the calibration stands: an effect must explain what it leaves, fitted with it
        basis = calibration_path.calibrated_basis(ask, evidence, calibration, handles, cal_runs, basis)
    elif again is None and calibration and calibration.get("superseded_by") and evidence.fits_pairs and \
            as_given[0]["shrink_pct"] >= basis.threshold and leaves_much(as_given[0], noise):
        # the calibration was kept, then set aside for the effect (effect_first): a mis-set value beside it?
        again = calibration_path.under_effect(ask, as_given[0], calibration, calib, holdout, folder, threshold)
    if again:
        # the values calibrated under an effect stand: the candidates are fitted on them
        calibration, cal_config, cal_runs = again
        handles = calibration_path.beside_effects(calibration, as_given)
        basis = calibration_path.calibrated_basis(ask, evidence, calibration, handles, cal_runs, basis)
    verdict = _verdict(ask, evidence, basis, noise, gate)
    if basis.calibrated and (verdict.finding or verdict.named and leaves_much(verdict.top(basis.ranking), noise)):
        basis, verdict = _effects_after_all(ask, evidence, calibration, basis, verdict, given, noise, gate)
    final_v = None      # the calibrated vector the final figures run on; None off the calibration path
    if basis.calibrated and verdict.named:
        calibration_path.rival_outdone(calibration, verdict.top(basis.ranking), gate, ask.progress)
    if basis.calibrated:
        hold_problem, final_v = calibration_path.settle(ask, calibration, handles, basis, verdict.named)
        basis = replace(basis, hold_problem=hold_problem)
    look = certainty.lookalike_step(basis.cal_problem, basis.ranking, basis.threshold,
                                    verdict.named and verdict.named_single and evidence.designs_experiments,
                                    ask.progress, ask.design_pair)
    look, sure = certainty.confidence_step(ask, evidence, basis, verdict, look, calibration, cal_config, as_given,
                                           noise)
    aug_hold, ba = _before_after_step(ask, evidence, basis, verdict, calibration, user_nominal_hold)
    model = result_mod.model_of(ask.config, calibration, handles, final_v, verdict.top(basis.ranking))
    result = result_mod.build(ask, basis, verdict, where, calibration, sure, look, noise, ba, model, t0)
    return result.as_dict(), {"holdout": basis.holdout, "nominal": user_nominal_hold, "augmented": aug_hold}


def _where_step(ask, evidence, calib, holdout):
    """[1] where the gap lies, with the user's config as given."""
    problem = fit.Problem(ask.sim, ask.config, calib, ask.mode)
    ask.progress(f"[1/4] where the gap lies: nominal simulation of {len(calib) + len(holdout)} run(s)")
    where = evidence.where(problem, list(calib) + list(holdout))
    for w in where["ranked"][:3]:
        ask.progress(evidence.where_line(w))
    return where


def _as_given(ask, evidence, calib, holdout, user_hold, floor, threshold):
    """The candidates fitted on the config as given: the basis they are first judged on."""
    cal_problem = fit.Problem(ask.sim, ask.config, calib, ask.mode)
    gaps = (cal_problem.gap(None, {}), user_hold.gap(None, {}))
    ranking, fits = cand.effects_step(ask, evidence, calib, holdout, user_hold, gaps)
    return Basis(calib, holdout, gaps, ranking, fits, ask.config, cal_problem, user_hold, floor, threshold)


def _verdict(ask, evidence, basis, noise, gate):
    """Whether the leader, or a pair on top of it, is named: it must clear the
    threshold and the noise gate, and leave nothing unexplained."""
    best = basis.ranking[0]
    _unresolved(ask, basis)
    ask.progress(f"      sensitivity floor of the held-out {evidence.noun}: {basis.floor:.1f}% "
                 f"(threshold {basis.threshold:.1f}%)")
    named_single = best["shrink_pct"] >= basis.threshold and basis.gaps[1] - best["holdout_gap"] >= gate
    if best["shrink_pct"] >= basis.threshold and not named_single:
        ask.progress(f"      {best['effect']} lowers the held-out gap by {basis.gaps[1] - best['holdout_gap']:.3f}, "
                     f"less than half the gap of the logs' own noise ({gate:.3f}): no evidence of an effect")
    pair_list, kept, second = (cand.pair_step(ask, basis, gate, noise) if evidence.fits_pairs and not basis.calibrated
                               else ([], None, None))
    finding = evidence.unexplained(basis.hold_problem, basis.holdout, basis.ranking,
                                   pairs.explaining(pair_list, kept), basis.gaps[1], noise,
                                   basis.threshold, ask.progress)
    named = (named_single or kept is not None) and finding is None
    lead = kept["effects"][0] if kept else best["effect"]     # a kept pair's first: its round's leader
    winner = lead if named else ("not explained" if finding else "none")
    effects = kept["effects"] if kept and named else ([winner] if named else [])
    return Verdict(named, named_single, pair_list, kept, second, finding, winner, effects)


def _unresolved(ask, basis):
    """Says which candidates would reach the threshold but are under the logs'
    resolution (candidates.rank ranked them last)."""
    for r in basis.ranking:
        if r.get("under_resolution") and r["shrink_pct"] >= basis.threshold:
            ask.progress(f"      {r['effect']} ({r['shrink_pct']:.1f}%) is under the logs' resolution: its fitted "
                         f"strokes all last less than one sample ({1e3 * ask.resolution_s:.0f} ms), which a "
                         f"log's own switch timing explains; ranked after the candidates the logs resolve")


def _effects_after_all(ask, evidence, calibration, basis, verdict, given, noise, gate):
    """The calibration stood against the best single effect but leaves the held-out
    runs unexplained, alone or with the effect named on it: its nominal values bent
    to mimic part of what two effects do (a pipe volume doubled for a pipe delay;
    the compressor, the vent and n moved for a thermal effect beside friction). The
    effects on the config as given, a pair included, are judged as if there had been
    no calibration; when they are named and leave a smaller held-out gap than the
    calibrated model (with its named effect) did, they stand and the calibration is
    set aside. When both name the same single effect, the config as given stands on
    that effect's own gap, not on a pair whose second it cannot name (_alt_gap).
    Returns the (basis, verdict) that stand."""
    named = verdict.top(basis.ranking) if verdict.named else None
    g_cal = named["holdout_gap"] if named else calibration["holdout_gap"]["after"]
    ask.progress(f"      the calibrated model{' with ' + named['effect'] if named else ''} leaves the held-out "
                 f"runs unexplained ({g_cal:.3f}): the effects on the config as given, pairs included")
    alt = _verdict(ask, evidence, given, noise, gate)
    explains = _alt_gap(ask, verdict, alt, given.ranking)
    if explains is None or alt.finding or not explains["holdout_gap"] < g_cal:
        ask.progress("      no better on the config as given: the calibration stands"
                     + (f" with {named['effect']}" if named else ", unexplained"))
        return basis, verdict
    calibration_path.set_aside(calibration, fx.combine(alt.effects), explains["holdout_gap"],
                               "explains what the calibration leaves unexplained; calibration not kept",
                               ask.progress)
    return given, alt


def _alt_gap(ask, verdict, alt, ranking):
    """The entry the config as given stands on against the calibrated model
    (_effects_after_all): what its verdict explains (Verdict.explains: a pair whose
    second is not told apart counts, against a calibration that names nothing).
    When the calibrated model names the same single effect, the two differ only in
    the calibration's values: the effect's own fit stands against them, since the
    unnamed second's share would be credited to no parameter and no effect (friction
    on a rig whose spring valve's Cd is 25 % low: friction with the Cd and damping
    calibrated 0.590, friction alone 2.345, friction + a second not told apart
    0.385: the pair, named as friction alone, set the right Cd aside, and which of
    the two landed lower moved with numpy's kernel set)."""
    explains = alt.explains(ranking)
    if explains is None or alt.kept or not verdict.named or verdict.effects != alt.effects:
        return explains
    if explains is not ranking[0]:
        ask.progress(f"      {ranking[0]['effect']} named on both: its fit alone ({ranking[0]['holdout_gap']:.3f}) "
                     f"against the calibration's values, not {explains['effect']} ({explains['holdout_gap']:.3f}) "
                     "whose second is not named")
    return ranking[0]


def _before_after_step(ask, evidence, basis, verdict, calibration, user_nominal_hold):
    """[4] the held-out runs under the final model against the config as given.
    Returns (augmented traces, the before/after tables)."""
    ask.progress(f"[4/4] before/after on held-out runs (the config as given against "
                 f"{'the calibrated config' if calibration and calibration['kept'] else 'the config'}"
                 f"{' + ' + fx.combine(verdict.effects) if verdict.named else ', no effect'})")
    top = verdict.top(basis.ranking)
    effect, params = (top["effect"], cand.values_of(top)) if top else (None, {})
    aug_hold = [basis.hold_problem.best_start(r, effect, params)[0] for r in basis.holdout]
    return aug_hold, evidence.before_after(basis.hold_problem, basis.holdout, user_nominal_hold, aug_hold)

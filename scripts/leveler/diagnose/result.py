"""diagnosis.json's content: the Diagnosis, in the file's order, and the model its
held-out figures ran on (--write-config)."""
import time
from dataclasses import dataclass, fields
from typing import Optional

from . import effects as fx
from .cplant import config_path
from .gap import shrink


@dataclass
class Diagnosis:
    """One diagnosis; as_dict() is diagnosis.json's object, keys in this order."""
    config: str
    mode: str
    calibration_runs: list
    holdout_runs: list
    threshold_pct: float
    sensitivity_floor_pct: float
    where: dict
    # the nominal parameters fitted before any effect (calibrate.py); None: not done
    calibration: Optional[dict]
    # how sure, and what no candidate explains (confidence.py)
    confidence: dict
    unexplained: Optional[dict]
    noise_gap: float
    ranking: list
    effect: str
    # the ranked combination: the leader, and a second effect when a pair is kept (pairs.py)
    effects: list
    pairs: list
    # second place of the ranked combination: what best explains what the leader leaves
    # (pairs.py; named only when kept), else, without pairs, the runner-up single
    second: Optional[dict]
    ranked_combination: list
    margin_pct: Optional[float]
    runner_up: Optional[str]
    # look-alikes: the candidates these logs cannot tell apart (the winner first), with evidence
    cannot_tell_apart: list
    separability: list
    experiment: Optional[dict]
    gap_before: dict
    gap_after: dict
    # the config as given -> the calibrated config with the named effect(s)
    shrink_pct: float
    # the named effect(s) alone, on top of the calibrated config
    effect_shrink_pct: float
    per_phase: dict
    events: list
    seconds: float
    # what the after-figures ran on (--write-config): exact values, not the report's digits
    model: dict

    def as_dict(self):
        """The fields in their order; values shared, not copied (the caller may add keys)."""
        return {f.name: getattr(self, f.name) for f in fields(self)}


def build(ask, basis, verdict, where, calibration, sure, look, noise, ba, model, t0):
    """The Diagnosis of the steps' outputs (pipeline.py); t0: when it started."""
    best = basis.ranking[0]
    runner = basis.ranking[1] if len(basis.ranking) > 1 else None
    second = verdict.second or runner
    return Diagnosis(
        config=ask.config, mode=ask.mode,
        calibration_runs=[r.name for r in basis.calib], holdout_runs=[r.name for r in basis.holdout],
        threshold_pct=basis.threshold, sensitivity_floor_pct=basis.floor, where=where,
        calibration=calibration, confidence=sure, unexplained=verdict.finding, noise_gap=noise,
        ranking=basis.ranking, effect=verdict.winner, effects=verdict.effects, pairs=verdict.pair_list,
        second=verdict.second or ({"effect": runner["effect"], "pair": None, "kept": False} if runner else None),
        ranked_combination=(list(fx.parts(second["pair"])) if second and second.get("pair")
                            else [best["effect"]] + ([second["effect"]] if second else [])),
        margin_pct=(best["shrink_pct"] - runner["shrink_pct"]) if runner else None,
        runner_up=runner["effect"] if runner else None,
        cannot_tell_apart=(look["lookalikes"] or {}).get("group", []),
        separability=(look["lookalikes"] or {}).get("tests", []),
        experiment=look["experiment"],
        gap_before=ba["overall"]["before"], gap_after=ba["overall"]["after"],
        shrink_pct=shrink(ba["overall"]["before"]["normalised"], ba["overall"]["after"]["normalised"]),
        effect_shrink_pct=(shrink(basis.gaps[1], (verdict.kept or best)["holdout_gap"]) if verdict.named else 0.0),
        per_phase=ba["per_phase"], events=ba["events"],
        seconds=time.perf_counter() - t0, model=model)


def model_of(config, calibration, handles, v, entry):
    """The model the verdict's held-out figures were simulated with, for --write-config:
    the config as given, the calibrated values (v: the vector the final figures used,
    None off the calibration path) and the named entry's effect values, each with where
    it came from. Values are the very floats the simulations had."""
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

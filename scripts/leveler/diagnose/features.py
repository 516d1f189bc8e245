"""Published event figures instead of traces (--features FILE).

The file is JSON:

    {"source": "...",
     "runs": [{"name": "thesis-900lb-exp", "config": "thesis-900lb", "role": "calibration",
               "schedule": {"base_load_n": 4003.4, "step_load_n": 889.6,
                            "step_on_s": 5, "step_off_s": 35, "end_s": 55},
               "features": {"lowest_height_m": 0.37084, ...}},
              {"name": "thesis-1000lb-exp", "config": "thesis-1000lb", "role": "holdout", ...}]}

Feature keys are leveler.events.SUMMARY_KEYS (SI; null = not published).
"schedule" is optional (default: the config's [scenario], as the C loader
resolves it) and "config" defaults to --config; the load over each 10 ms tick
follows the simulator's own scenario rule (engine.scenario_loads). Each run is simulated closed loop
with the firmware, its event figures extracted as for a trace, and the
residual is the difference to the published figures in units of the
figures' published resolution (FEATURE_SCALE).
"""
import json
import math
import os

import numpy as np

from leveler import config as config_mod
from leveler import engine, events, thesis

from . import cplant, gap, runs
from .errors import DiagnoseInputError

# One unit of error per figure: the resolution the thesis quotes them in.
FEATURE_SCALE = {"length": 0.05 * thesis.M_PER_IN, "pressure": thesis.PA_PER_PSI, "time": 1.0}
KIND = {k: ("length" if k.endswith("_m") else "pressure" if k.endswith("_pa") else "time")
        for k in events.SUMMARY_KEYS}
MISSING_PENALTY = 5.0   # a figure the simulation does not produce at all (in scale units)


class FeatureRun:
    """A run known only by its event figures; simulated closed loop on its schedule."""

    def __init__(self, name, config, schedule, features):
        self.name = self.path = name
        self.config_override = config
        self.features = features
        end = schedule["end_s"]
        self.t_s = engine.tick_grid(end)
        self.load_n = engine.scenario_loads(self.t_s, schedule)
        nan = np.full(len(self.t_s), np.nan)
        self.signals = {s: nan for s in runs.SIGNALS}
        self.commands = {}
        self.has_commands = False

    def measured(self, signal):
        return False

    def figures(self, trace):
        return gap.event_figures(trace.t_s, trace.signals, self.load_n, gap.band_of(self.config_override))

    def residual_vector(self, trace):
        sim = self.figures(trace)
        r = []
        for k, v in self.features.items():
            s = sim.get(k)
            r.append(MISSING_PENALTY if s is None else (s - v) / FEATURE_SCALE[KIND[k]])
        return np.array(r) / math.sqrt(max(len(r), 1))


def _scenario(config):
    """The [scenario] of a plant config by name, as the C loader resolves it."""
    path = cplant.config_path(config)
    try:
        values = config_mod.load(path).values["scenario"]
    except config_mod.ConfigError as e:
        raise DiagnoseInputError(str(e)) from None
    return {k: float(values[k]) for k in engine.SCENARIO_KEYS}


def load_many(paths, default_config):
    """Several files: runs without a role are calibration in the first file, held out in the others."""
    calib, hold = [], []
    for i, p in enumerate(paths):
        c, h = load(p, default_config, "calibration" if i == 0 else "holdout", check=False)
        calib += c
        hold += h
    if not calib or not hold:
        raise DiagnoseInputError(f"{', '.join(paths)}: need at least one calibration and one holdout run "
                                 f"(give \"role\" per run, or a second --features file to hold out)")
    return calib, hold


def load(path, default_config, default_role="calibration", check=True):
    """(calibration runs, holdout runs) from a features file. DiagnoseInputError on bad input."""
    try:
        with open(path) as fh:
            doc = json.load(fh)
    except OSError as e:
        raise DiagnoseInputError(f"{path}: cannot read: {e.strerror}") from None
    except json.JSONDecodeError as e:
        raise DiagnoseInputError(f"{path}:{e.lineno}: not JSON: {e.msg}") from None
    if isinstance(doc, dict) and "runs" not in doc and any(k in KIND for k in doc):
        # a flat summary (leveler.events keys), optionally with config / schedule / role
        doc = {"runs": [{"name": os.path.splitext(os.path.basename(path))[0],
                         "config": doc.get("config"), "schedule": doc.get("schedule"),
                         "role": doc.get("role", default_role),
                         "features": {k: v for k, v in doc.items()
                                      if k not in ("config", "schedule", "role", "name")}}]}
    if not isinstance(doc, dict) or not isinstance(doc.get("runs"), list) or not doc["runs"]:
        raise DiagnoseInputError(f"{path}: expected an object with a non-empty list \"runs\" "
                                 f"or a flat object of event figures")
    calib, hold = [], []
    for i, r in enumerate(doc["runs"]):
        where = f"{path}: runs[{i}]"
        feats = r.get("features")
        if not isinstance(feats, dict):
            raise DiagnoseInputError(f"{where}: missing object \"features\"")
        clean = {}
        for k, v in feats.items():
            if k not in KIND:
                raise DiagnoseInputError(f"{where}: features.{k}: unknown figure (known: "
                                         f"{', '.join(events.SUMMARY_KEYS)})")
            if v is None:
                continue
            if not isinstance(v, (int, float)) or not math.isfinite(v):
                raise DiagnoseInputError(f"{where}: features.{k}: not a number: {v!r}")
            lo, hi = {"length": (0.05, 1.5), "pressure": (2e4, 3e6), "time": (0.0, 1e4)}[KIND[k]]
            if not lo <= v <= hi:
                raise DiagnoseInputError(f"{where}: features.{k} = {v:g} is outside {lo:g}..{hi:g} "
                                         f"(SI: m, Pa absolute, s)")
            clean[k] = float(v)
        if not clean:
            raise DiagnoseInputError(f"{where}: no published figure")
        config = r.get("config") or default_config
        sched = _scenario(config)
        for k, v in (r.get("schedule") or {}).items():
            if k not in sched:
                raise DiagnoseInputError(f"{where}: schedule.{k}: unknown key (known: {', '.join(sched)})")
            sched[k] = float(v)
        run = FeatureRun(r.get("name") or f"run{i}", config, sched, clean)
        role = r.get("role") or default_role
        if role not in ("calibration", "holdout"):
            raise DiagnoseInputError(f"{where}: role must be calibration or holdout, not {role!r}")
        (calib if role == "calibration" else hold).append(run)
    if check and (not calib or not hold):
        raise DiagnoseInputError(f"{path}: need at least one calibration and one holdout run")
    return calib, hold


def thesis_experiment_file(path):
    """Writes the thesis experiment table (README, leveler.thesis) as a features file:
    900 lb for calibration, 1000 lb held out."""
    runs = []
    for case, config, role in (("thesis-900lb-exp", "thesis-900lb", "calibration"),
                               ("thesis-1000lb-exp", "thesis-1000lb", "holdout")):
        runs.append({"name": case, "config": config, "role": role,
                     "features": {k: v for k, v in thesis.CASES[case].items() if v is not None}})
    doc = {"source": "thesis Chapter IV experiment (README table), SI", "runs": runs}
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    with open(path, "w") as fh:
        json.dump(doc, fh, indent=2)
        fh.write("\n")


# The thesis's accumulator experiment (Chapter IV): case -> config with that charge.
ACCUMULATOR_CONFIGS = {
    "thesis-900lb-acc90psig-exp": "thesis-900lb-diaphragm-90psig",
    "thesis-900lb-acc100psig-exp": "thesis-900lb-diaphragm-100psig",
    "thesis-900lb-acc112psig-exp": "thesis-900lb-diaphragm",
    "thesis-1000lb-acc100psig-exp": "thesis-1000lb-diaphragm-100psig",
    "thesis-1000lb-acc110psig-exp": "thesis-1000lb-diaphragm-110psig",
}


def thesis_accumulator_file(path):
    """Writes the thesis accumulator experiment figures (leveler.thesis.CASES) as a
    features file: 900 lb for calibration, 1000 lb held out. The 1000 lb, 120 psig
    run ("no time delay") has no figure and is left out."""
    from leveler import thesis
    runs = []
    for case, config in ACCUMULATOR_CONFIGS.items():
        feats = {k: v for k, v in thesis.CASES[case].items() if v is not None}
        runs.append({"name": case, "config": config, "role": "calibration" if "900lb" in case else "holdout",
                     "features": feats})
    doc = {"source": "thesis Chapter IV accumulator experiment (diaphragm, +200 lb), SI", "runs": runs}
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    with open(path, "w") as fh:
        json.dump(doc, fh, indent=2)
        fh.write("\n")

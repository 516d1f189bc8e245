"""A spring that loses air with its valves shut: a gap no nominal value explains.

Until a log's first valve switch or load change the spring is a closed volume:
no discharge coefficient, compressor or vent acts on it, and a platform held by
the rubber's hysteresis does not move, so the config's model holds P2 still
whatever its values. A P2 that falls there is air leaving the spring. The leak
candidate fitted on those stretches alone (the calibration runs' quiet starts)
sizes it before any value is calibrated; the values are then calibrated with it
in the model (calibration_path.under_leak). A leak beside a mis-set value hides
from each alone: with a vent 25 % weak and a leak, the vent's Cd alone fits
worse than the config's, the leak alone fits nothing, and the calibration bends
the compressor and the damping instead."""
from dataclasses import replace

import numpy as np

from . import effects as fx
from . import fit
from .calibrate import worth_adding
from .start_state import QUIET_MAX_S, quiet_end

LEAK = "leak"


def stretch(run):
    """The run up to its first valve switch or load change, or None when that is
    shorter than QUIET_MAX_S (too short to see air leave) or the log does not say
    when its valves switched (published figures, a log without actuator columns)."""
    if not getattr(run, "has_commands", False):
        return None
    end = quiet_end(run, None)
    if run.t_s[end - 1] - run.t_s[0] < QUIET_MAX_S:
        return None
    return replace(run, t_s=run.t_s[:end], signals={s: v[:end] for s, v in run.signals.items()},
                   load_n=run.load_n[:end], commands={c: v[:end] for c, v in run.commands.items()},
                   start_shift=(0.0, _start_lag_pa(run, end)))


def _start_lag_pa(run, end):
    """The replay starts P2 at its mean over the quiet start (start_state): a
    falling P2's mean is that of the window's middle, not its start. The P2 a
    straight line through the stretch gives at its start, less that mean (0
    for a still P2): without it, a leak fitted there is sized a third short."""
    t, p2 = run.t_s[:end] - run.t_s[0], run.signals["p_spring_pa"][:end]
    ok = np.isfinite(p2)
    q = quiet_end(run)
    if ok.sum() < 2 or not ok[:q].any():
        return 0.0
    slope = np.polyfit(t[ok], p2[ok], 1)[0]
    return float(-slope * np.mean(t[:q][ok[:q]]))


def leak_seen(ask, calib):
    """The leak the calibration runs' shut stretches show: {effect, params, seconds,
    gap: [without, with]} when fitted there it pays for its parameter (the
    information criterion the calibration's values must meet) and lowers the
    stretches' gap by the noise gate (half the gap their own noise leaves: a
    compressor 15 % weak "shows" a leak of 1.2e-9 m^2 that lowers it 0.109 ->
    0.104), else None."""
    if LEAK not in ask.candidates:
        return None
    short = [s for s in (stretch(r) for r in calib) if s is not None]
    if not short:
        return None
    problem = fit.Problem(ask.sim, ask.config, short, ask.mode)
    r0 = problem.residual_vector(None, {})
    found = fit.fit_effect(problem, fx.get(LEAK))
    r1 = problem.residual_vector(LEAK, found["params"])
    n = len(short)
    gaps = [fit.cost_to_gap(r0, n), fit.cost_to_gap(r1, n)]
    if not worth_adding(r0, float(np.sum(r1 ** 2))) or gaps[0] - gaps[1] < fit.NOISE_GAIN * fit.noise_gap(short):
        return None
    return {"effect": LEAK, "params": dict(found["params"]),
            "seconds": [float(s.t_s[-1] - s.t_s[0]) for s in short], "gap": gaps}

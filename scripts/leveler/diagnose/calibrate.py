"""Calibrate before blaming: the nominal parameters of the rig's own config,
fitted on the calibration runs before any unmodelled effect is tried.

A new rig's first gap is usually a value set wrong in its config, not an
effect the model lacks: a compressor worn to less displacement, a discharge
coefficient guessed, a spring volume measured at another height, damping
taken from a datasheet, the polytropic exponent (the thesis's Appendix A
studies n = 1.0 / 1.1 / 1.4). The parameters below are the ones a user sets
by hand and that the logged signals can see: each moves a different part of
the step test (P1's climb, the fill, the vent, the stiffness, the speeds).
They are chosen from the physics, each with a physical range; nothing here is
taken from a test set.

The fit: every parameter in a unit box (log-mapped for scale factors), a weak
prior toward the config's value (two percent of a unit gap per doubling: far
below any signal, so only directions the logs cannot see stay put), one
least-squares fit from the config's values. The runs are simulated through the
one C loader: a config that `include`s the user's and sets the fitted keys (SI
keys, as `leveler-sim --dump-config` names them).

Each parameter gets the Jacobian's 95 % interval (uncertainty.py), an
identifiability flag and `moved`: identifiable, its interval excludes the
config's value and the change is material. The calibration is kept only when
it shrinks the held-out gap beyond the threshold an effect must pass; then the
effects are fitted on top of it, so an effect is named only for what
calibration cannot explain on the held-out run (pipeline.py).
"""
import copy
import hashlib
import math
import multiprocessing
import os
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from leveler import config as leveler_config

from . import fit
from .cplant import config_path
from .gap import shrink as shrink_pct
from .effects import from_unit
from .uncertainty import Z95, autocorrelation_inflation, jacobian, unit_covariance

PRIOR_PER_DOUBLING = 0.02   # prior residual for a factor 2 (or a range's width) away from the config
MATERIAL_REL = 0.03         # a change below 3 % is not reported as moved (unless it carries the gain)
ALIKE_SHARE = 0.10          # values alike when alone they leave held-out gaps within 10 % (as calibration/effect)
# No interval narrower than +-1 % of the value: the plant model replays a rig to about
# that (a compressor 15 % weak came back -14.9 % with a Jacobian interval of +-0.01 %).
MODEL_FLOOR_REL = 0.01
UNIDENTIFIABLE_LOG = math.log(2.0)   # a 95 % interval wider than a factor 2 either way


@dataclass(frozen=True)
class Nominal:
    """One config key the calibration may move. rel: (low, high) factors of the
    config's value (log-mapped); absolute: (low, high) values; cap: a hard upper bound."""
    name: str
    section: str
    key: str
    why: str
    rel: tuple = None
    absolute: tuple = None
    cap: float = None
    accumulator: tuple = ()     # only on rigs with one of these accumulator types

    def bounds(self, value):
        if self.absolute:
            return self.absolute
        lo, hi = value * self.rel[0], value * self.rel[1]
        return lo, min(hi, self.cap) if self.cap else hi

    @property
    def log(self):
        return self.absolute is None


NOMINALS = (
    Nominal("compressor_capacity", "compressor", "capacity_m3_per_rad", rel=(0.6, 1.5),
            why="displacement per radian: wear or another head; sets how fast P1 climbs with the compressor on"),
    Nominal("spring_valve_cd_in", "spring_valve", "cd_into_spring", rel=(0.5, 1.8), cap=1.0,
            why="discharge coefficient pipe -> spring: how fast the spring fills through the valve"),
    Nominal("spring_valve_cd_out", "spring_valve", "cd_out_of_spring", rel=(0.5, 1.8), cap=1.0,
            why="discharge coefficient spring -> pipe: how fast the spring empties toward the vent"),
    Nominal("vent_valve_cd", "vent_valve", "cd", rel=(0.5, 1.8), cap=1.0,
            why="discharge coefficient of the vent: how fast the pipe discharges to ambient"),
    Nominal("spring_volume", "spring", "volume_m3", rel=(0.8, 1.25),
            why="the spring's volume at the initial height: its stiffness, P2 against height"),
    Nominal("pipe_volume", "pipe", "volume_m3", rel=(0.5, 2.0),
            why="the pipe's volume: how P1 moves for a given flow"),
    Nominal("damping_up", "platform", "damping_up_n_s_per_m", rel=(0.4, 2.5),
            why="platform damping rising: the climb's speed for a given excess pressure"),
    Nominal("damping_down", "platform", "damping_down_n_s_per_m", rel=(0.4, 2.5),
            why="platform damping sinking: the drop's speed"),
    Nominal("polytropic_exponent", "ambient", "polytropic_exponent", absolute=(1.0, 1.4),
            why="the gas's exponent (Appendix A: 1.0 isothermal .. 1.4 adiabatic): stiffness in fast motion"),
    Nominal("accumulator_cd", "accumulator", "cd", rel=(0.5, 1.8), cap=1.0, accumulator=("tube", "diaphragm"),
            why="discharge coefficient of the accumulator valve: how fast the accumulator's burst arrives"),
    Nominal("accumulator_volume", "accumulator", "volume_m3", rel=(0.7, 1.4), accumulator=("tube",),
            why="the accumulator's gas volume: how much air one burst holds"),
    Nominal("accumulator_charge", "accumulator", "charge_pa", rel=(0.85, 1.15), accumulator=("tube",),
            why="the accumulator's charge pressure: the burst's pressure"),
)


def applicable(resolved):
    """The Nominal entries that exist on this rig (accumulator keys only with one)."""
    acc = resolved.get("accumulator", {}).get("type", "none")
    return [n for n in NOMINALS if not n.accumulator or acc in n.accumulator]


class Space:
    """The calibration's unit box over a rig's applicable parameters."""

    def __init__(self, config_file, resolved):
        self.config_file = config_file
        self.name = resolved["config"]["name"]
        self.params = applicable(resolved)
        self.base = np.array([resolved[n.section][n.key] for n in self.params], dtype=float)
        self.lo = np.array([n.bounds(v)[0] for n, v in zip(self.params, self.base)])
        self.hi = np.array([n.bounds(v)[1] for n, v in zip(self.params, self.base)])
        self.is_log = np.array([n.log for n in self.params])
        self.u0 = self.to_unit(self.base)

    def _t(self, v):
        v = np.asarray(v, dtype=float)
        return np.where(self.is_log, np.log(np.maximum(v, 1e-300)), v)

    def to_unit(self, values):
        lo, hi = self._t(self.lo), self._t(self.hi)
        return np.clip((self._t(values) - lo) / (hi - lo), 0.0, 1.0)

    def values(self, u):
        lo, hi = self._t(self.lo), self._t(self.hi)
        x = lo + np.clip(u, 0.0, 1.0) * (hi - lo)
        # at the config's point, the config's own value (not exp(log(v)), one ulp away)
        return np.where(np.asarray(u) == self.u0, self.base, np.where(self.is_log, np.exp(x), x))

    def stretched(self, j, uj):
        """A value pinned at the end of its range where that end is a chosen span, not a
        physical limit (a factor of the config's value, not n = 1 or 1.4 or Cd = 1): the
        value is standing in for something else, not mis-set."""
        n = self.params[j]
        at_lo, at_hi = uj <= 1e-3, uj >= 1.0 - 1e-3
        physical_hi = n.absolute is not None or (n.cap is not None and self.hi[j] >= n.cap)
        return (at_lo and n.absolute is None) or (at_hi and not physical_hi)

    def prior(self, u):
        """Weak pull toward the config: PRIOR_PER_DOUBLING per factor 2 (per range for absolute keys)."""
        width = self._t(self.hi) - self._t(self.lo)
        per = np.where(self.is_log, math.log(2.0) / width, 1.0)
        return PRIOR_PER_DOUBLING * (np.asarray(u) - self.u0) / per


def ini_text(config_file, name, params, values, notes=None):
    """A config that includes the user's and sets the calibrated keys (SI)."""
    lines = [f"[config]\ninclude = {os.path.abspath(config_file)}\nname = {name}\n"]
    by_section = {}
    for i, (n, v) in enumerate(zip(params, values)):
        note = f"  ; {notes[i]}" if notes and notes[i] else ""
        by_section.setdefault(n.section, []).append(f"{n.key} = {float(v)!r}{note}")
    for sec, keys in by_section.items():
        lines.append(f"\n[{sec}]\n" + "\n".join(keys) + "\n")
    return "".join(lines)


def _carried(space, values, other):
    """The calibration's values at `space` carried to another config's space by
    parameter: the same factor (the same value for absolute keys); a parameter the
    calibrated config does not have (an accumulator's, when --config has none)
    keeps the other config's own value."""
    mine = {(n.section, n.key): j for j, n in enumerate(space.params)}
    out = np.array(other.base, dtype=float)
    for i, n in enumerate(other.params):
        j = mine.get((n.section, n.key))
        if j is not None:
            out[i] = other.base[i] * values[j] / space.base[j] if other.is_log[i] else values[j]
    return out


class Calibrated:
    """Residuals of the runs under a parameter vector: the C loader reads a
    written config (one file per vector, kept for the caches keyed by path).
    effect: (name, {param: value}) held in the model while the values are fitted
    (calibration under an effect already found), else None."""

    def __init__(self, sim, space, runs, mode, folder, start_shifts=None, effect=None):
        self.sim, self.space, self.runs, self.mode, self.folder = sim, space, runs, mode, folder
        self.start_shifts = start_shifts
        self.effect = effect
        self.own = {}        # config name -> Space of runs with their own config
        self.nsim = 0

    def without_effect(self):
        return Calibrated(self.sim, self.space, self.runs, self.mode, self.folder, self.start_shifts)

    def config(self, u, space=None):
        """The config file of the parameters at u: the space's own values, or for
        another config of the same rig (space: a run's own, published figures) the
        same factors (the same values for absolute keys) applied to its values."""
        values = self.space.values(u)
        if space is not None:
            values = _carried(self.space, values, space)
        sp = space or self.space
        text = ini_text(sp.config_file, sp.name, sp.params, values)
        path = os.path.join(self.folder, "cal-" + hashlib.sha1(text.encode()).hexdigest()[:16] + ".ini")
        if not os.path.exists(path):
            with open(path + ".tmp", "w") as fh:
                fh.write(text)
            os.replace(path + ".tmp", path)
        return path

    def runs_at(self, u):
        """The runs, those with a config of their own (published figures) pointed at its
        calibrated version."""
        out = []
        for r in self.runs:
            own = getattr(r, "config_override", None)
            if own:
                if own not in self.own:
                    path = config_path(own)
                    self.own[own] = Space(path, leveler_config.resolved(path))
                r = copy.copy(r)
                r.config_override = self.config(u, self.own[own])
            out.append(r)
        return out

    def problem(self, u):
        return fit.Problem(self.sim, self.config(u), self.runs_at(u), self.mode, self.start_shifts)

    def data_residual(self, u):
        p = self.problem(u)
        r = p.residual_vector(*(self.effect or (None, {})))
        self.nsim += p.nsim
        return r

    def data_cost_below(self, u, bound):
        """The data residual's sum of squares, or None once it reaches bound (fit.Problem.cost_below)."""
        p = self.problem(u)
        c = p.cost_below(*(self.effect or (None, {})), bound)
        self.nsim += p.nsim
        return c

    def residual(self, u):
        return np.concatenate([self.data_residual(u), self.space.prior(u)])

    def gap(self, u):
        p = self.problem(u)
        g = p.gap(*(self.effect or (None, {})))
        self.nsim += p.nsim
        return g


MAX_MOVED = 4          # a config is mis-set in a few values, not in all of them


def fit_subset(cal, u, idx, max_nfev):
    """Least squares over the parameters idx (the others held at u). Returns the unit point."""
    idx = list(idx)

    def fun(x):
        v = np.array(u, dtype=float)
        v[idx] = x
        return cal.residual(v)
    res = least_squares(fun, np.asarray(u, dtype=float)[idx], bounds=(np.zeros(len(idx)), np.ones(len(idx))),
                        diff_step=0.01, x_scale=np.full(len(idx), 0.2), max_nfev=max_nfev, method="trf")
    out = np.array(u, dtype=float)
    out[idx] = res.x
    return out


MIN_SS_GAIN = 0.05     # and lower the calibration residual's sum of squares by 5 %
GRID = 9               # points across a parameter's range, then as many again around the best


def _grid_best(cal, u, j, xs, best, best_ss, seen):
    """The best of u with parameter j at each of xs not in `seen` (points already
    simulated: the fine grid's ends and middle are coarse points), and best/best_ss."""
    for x in xs:
        if any(abs(x - y) < 1e-12 for y in seen):
            continue
        seen.append(x)
        v = np.array(u, dtype=float)
        v[j] = x
        ss = cal.data_cost_below(v, best_ss)    # None: its first runs already cost more
        if ss is not None and ss < best_ss:
            best, best_ss = v, ss
    return best, best_ss


def grid_start(cal, u, j, ss_u):
    """u with parameter j at the best of a grid over its range (or where it is), the
    grid refined once around its best point (a step of 1/32 of the range). The closed
    loop can make the residual rough in a single value (a valve's switching moves by
    whole ticks); a local fit from the config's value can stay on such a ridge, from
    the grid's best it does not (test_calibrate's stand-in). ss_u: the residual's sum
    of squares at u (the caller has it)."""
    seen = [float(u[j])]
    best, best_ss = _grid_best(cal, u, j, np.linspace(0.0, 1.0, GRID), np.array(u, dtype=float), ss_u, seen)
    step = 1.0 / (GRID - 1)
    fine = np.clip(best[j] + np.linspace(-step, step, GRID), 0.0, 1.0)
    return _grid_best(cal, u, j, fine, best, best_ss, seen)[0]


def worth_adding(r_old, ss_new):
    """The Bayesian information criterion with the residuals' effective sample
    count (autocorrelation, uncertainty.py): one more parameter must pay for
    itself, and make a difference worth reporting (MIN_SS_GAIN)."""
    ss_old = float(np.sum(r_old ** 2))
    if ss_new <= 0.0 or ss_old <= 0.0:
        return ss_new < ss_old
    if ss_new > (1.0 - MIN_SS_GAIN) * ss_old:
        return False
    n_eff = max(len(r_old) / autocorrelation_inflation(r_old), 2.0)
    return n_eff * math.log(ss_new / ss_old) + math.log(n_eff) < 0.0


def fit_calibration(cal, max_nfev=12, progress=None, jobs=1, first=None, path=None):
    """Forward selection: each round fits every parameter not yet chosen alone
    (the chosen ones held; from the best of a grid over its range, grid_start), adds
    the one that lowers the calibration residual most if it pays for itself
    (worth_adding), then refits the chosen set jointly.
    One parameter at a time finds the value that is wrong; a joint fit of all
    of them from the config trades small compensating errors among the rest.
    A value that ends pinned at the end of its span is not taken (Space.stretched).
    Returns (unit point, chosen indices, {index: unit point} of the first round: each
    parameter fitted alone from the config, where not pinned at a chosen span's end).
    jobs: processes for a round's trials. first: (index, unit point) taken as the
    first choice instead of the first round's (held_out_first). path: a list that
    gets (unit point, chosen) after each value added."""
    u = np.array(cal.space.u0, dtype=float) if first is None else np.array(first[1], dtype=float)
    chosen, singles = ([] if first is None else [first[0]]), None
    r = cal.data_residual(u)
    if path is not None and chosen:
        path.append((u, list(chosen)))
    with _TrialPool(cal, jobs) as trials_of:
        while len(chosen) < min(MAX_MOVED, len(u)):
            ss_u = float(np.sum(r ** 2))
            trials = trials_of(u, [j for j in range(len(u)) if j not in chosen], ss_u, max_nfev)
            scored = [(ss, j, v) for j, v, ss in trials if ss is not None]
            singles = {j: v for _, j, v in scored} if singles is None else singles
            if not scored:
                break
            ss, j, v = min(scored, key=lambda x: x[0])
            if not worth_adding(r, ss):
                break
            chosen.append(j)
            u = fit_subset(cal, v, chosen, 2 * max_nfev) if len(chosen) > 1 else v
            r = cal.data_residual(u)
            if path is not None:
                path.append((u, list(chosen)))
            if progress:
                progress(f"      + {cal.space.params[j].name:<22} calibration gap {fit.cost_to_gap(r, len(cal.runs)):.3f}")
    return u, chosen, singles or {}


def _trial(cal, u, j, ss_u, max_nfev):
    """Parameter j fitted alone from the grid's best (the others held at u): (j, unit
    point, the calibration residual's sum of squares there or None when the value
    is pinned at its span's end, simulations run)."""
    n0 = cal.nsim
    v = fit_subset(cal, grid_start(cal, u, j, ss_u), [j], max_nfev)
    ss = None if cal.space.stretched(j, v[j]) else float(np.sum(cal.data_residual(v) ** 2))
    return j, v, ss, cal.nsim - n0


_forked = {}


def _forked_trial(args):
    return _trial(_forked["cal"], *args)


class _TrialPool:
    """A round's single-parameter trials, in `jobs` forked processes (each trial is
    independent and deterministic: the same values as one after the other, in the
    same order). Called as trials_of(u, indices, ss_u, max_nfev) -> [(j, v, ss)]."""

    def __init__(self, cal, jobs):
        self.cal, self.jobs, self.pool = cal, jobs or 1, None

    def __enter__(self):
        if self.jobs > 1 and "fork" in multiprocessing.get_all_start_methods():
            _forked["cal"] = self.cal   # the children inherit it: the simulator is not pickled
            self.pool = ProcessPoolExecutor(self.jobs, mp_context=multiprocessing.get_context("fork"))
        return self

    def __exit__(self, *exc):
        if self.pool is not None:
            self.pool.shutdown()
            _forked.pop("cal", None)

    def __call__(self, u, todo, ss_u, max_nfev):
        args = [(u, j, ss_u, max_nfev) for j in todo]
        out = list(self.pool.map(_forked_trial, args)) if self.pool else [_trial(self.cal, *a) for a in args]
        if self.pool:
            self.cal.nsim += sum(n for *_, n in out)
        return [(j, v, ss) for j, v, ss, _ in out]


def carries_gain(hold, u, chosen, before, after):
    """Per chosen index: whether setting it alone back to the config's value gives back
    at least half the calibration's held-out gain (before - after). Such a value
    matters however small its change: the spring's volume 1.4 % larger holds the same
    air as a pipe 30 % larger."""
    out = {}
    for j in chosen:
        v = np.array(u, dtype=float)
        v[j] = hold.space.u0[j]
        out[j] = hold.gap(v) - after >= 0.5 * (before - after)
    return out


def alike_values(cal, hold, singles, first, share):
    """Other values that, each fitted alone, explain the held-out runs as well as the
    first one chosen fitted alone (a held-out gap within `share`), by a material
    change: the set the logs cannot tell apart. [{name, value, change_pct, holdout_gap}]"""
    if first not in singles:
        return []
    sp, g_first = cal.space, hold.gap(singles[first])
    out = []
    for k, v in singles.items():
        change = sp.values(v)[k] / sp.base[k] - 1.0
        if k == first or abs(change) < MATERIAL_REL:
            continue
        g = hold.gap(v)
        if g <= (1.0 + share) * g_first:
            out.append({"name": sp.params[k].name, "value": float(sp.values(v)[k]), "change_pct": 100.0 * change,
                        "holdout_gap": g, "first_holdout_gap": g_first})
    return out


def held_out_first(cal, hold, singles, chosen, alike, after, max_nfev, jobs, progress):
    """The calibration again from the alike value that alone explains the held-out
    runs best, when that is not the first one chosen: values the calibration runs
    cannot tell apart are told apart by the held-out runs (and by an experiment
    among them), as effects are (a pipe 30 % larger fits the steps as well as a
    lower polytropic exponent; the compressor against the shut valve says which).
    The second calibration stops where the held-out runs are best along its path: a
    value added because it lowers the calibration runs' gap (the compressor after a
    larger pipe) can leave the held-out runs worse than the alike value alone.
    Returns (u, chosen, held-out gap) of the other when it is the better on the
    held-out runs, else None."""
    better = [a for a in alike if a["holdout_gap"] < a["first_holdout_gap"]]
    if not better:
        return None
    a = min(better, key=lambda x: x["holdout_gap"])
    k = [n.name for n in cal.space.params].index(a["name"])
    progress(f"      {a['name']} alone explains the held-out runs better than {cal.space.params[chosen[0]].name} "
             f"alone ({a['holdout_gap']:.3f} against {a['first_holdout_gap']:.3f}): calibrating from it")
    path = []
    fit_calibration(cal, max_nfev, progress, jobs, first=(k, singles[k]), path=path)
    g2, u2, chosen2 = min(((hold.gap(u), u, c) for u, c in path), key=lambda x: x[0])
    if len(chosen2) < len(path[-1][1]):
        progress(f"      from {a['name']}: the held-out runs are best with {', '.join(cal.space.params[j].name for j in chosen2)}")
    progress(f"      from {a['name']}: held-out gap {g2:.3f} against {after:.3f}, "
             + ("taken" if g2 < after else "the first calibration stands"))
    return (u2, chosen2, g2) if g2 < after else None


def _sd(cal, u, chosen):
    """Unit-box standard deviations of the chosen parameters (the Jacobian's, over
    the chosen set); inf for the others (the logs were not asked for them)."""
    sd = np.full(len(u), np.inf)
    if not chosen:
        return sd

    def fun(x):
        v = np.array(u, dtype=float)
        v[chosen] = x
        return cal.data_residual(v)
    r, J = jacobian(fun, np.asarray(u, dtype=float)[chosen], step=0.01)
    cov, blind = unit_covariance(r, J)
    for k, j in enumerate(chosen):
        sd[j] = float(np.sqrt(max(cov[k, k], 0.0))) if not blind[k] else np.inf
    return sd


def over_runs(cal, u, chosen, max_nfev=12):
    """The chosen values refitted on each calibration run alone (from u): what another
    run would give. The Jacobian's interval sees only the noise; a model that differs
    from the rig in ways the fit cannot see (a replay between samples, an effect) moves
    the values from run to run, and that spread belongs in the interval."""
    if len(cal.runs) < 2 or not chosen:
        return []
    out = []
    for k in range(len(cal.runs)):
        sub = Calibrated(cal.sim, cal.space, [cal.runs[k]], cal.mode, cal.folder, effect=cal.effect)
        out.append(cal.space.values(fit_subset(sub, u, chosen, max_nfev)))
        cal.nsim += sub.nsim
    return out


def parameter_table(cal, u, chosen, accepted, matters=None):
    """Per parameter: config value, calibrated value, change, 95 % interval (the
    Jacobian's, widened to hold the refits on each run alone), flags."""
    sds = _sd(cal, u, chosen)
    refits = over_runs(cal, u, chosen)
    sp = cal.space
    vals = sp.values(u)
    out = []
    for j, n in enumerate(sp.params):
        sd = float(sds[j])
        lo_u, hi_u = np.array(u, dtype=float), np.array(u, dtype=float)
        lo_u[j] = max(0.0, u[j] - Z95 * sd) if np.isfinite(sd) else 0.0
        hi_u[j] = min(1.0, u[j] + Z95 * sd) if np.isfinite(sd) else 1.0
        lo, hi = float(sp.values(lo_u)[j]), float(sp.values(hi_u)[j])
        base, v = float(sp.base[j]), float(vals[j])
        if j in chosen:     # each run alone, mirrored about the value, and the model's own fidelity
            d = max([abs(float(r[j]) - v) for r in refits] + [MODEL_FLOOR_REL * abs(v)])
            lo, hi = max(min(lo, v - d), float(sp.lo[j])), min(max(hi, v + d), float(sp.hi[j]))
        ident = bool(j not in chosen or np.isfinite(sd) and (math.log(max(hi, 1e-300) / max(lo, 1e-300)) < 2 * UNIDENTIFIABLE_LOG
                                          if n.log else hi - lo < 0.5 * (sp.hi[j] - sp.lo[j])))
        change = v / base - 1.0 if base != 0 else 0.0
        material = abs(change) >= MATERIAL_REL or (matters or {}).get(j, False)
        moved = bool(accepted and j in chosen and ident and not (lo <= base <= hi) and material)
        out.append({"name": n.name, "section": n.section, "key": n.key, "config": base, "value": v,
                    "change_pct": 100.0 * change, "interval": [lo, hi], "range": [float(sp.lo[j]), float(sp.hi[j])],
                    "identifiable": ident, "at_bound": bool(u[j] <= 1e-3 or u[j] >= 1 - 1e-3),
                    "over_runs": [float(r[j]) for r in refits] if j in chosen else [],
                    "chosen": j in chosen, "moved": moved, "why": n.why})
    return out


def supported(sim):
    """The C plant (a stand-in simulator has no config files)."""
    return hasattr(sim, "check_config")


def calibrate(sim, config_file, calib, holdout, mode, folder, threshold, progress=print, max_nfev=12, jobs=1,
              effect=None):
    """The calibration stage. Returns its report (diagnosis.json's `calibration`)
    with `config_file`: the calibrated config when kept, else the user's. effect:
    (name, params) held in the model (the gaps before and after include it)."""
    t0 = time.perf_counter()
    space = Space(config_file, leveler_config.resolved(config_file))
    cal = Calibrated(sim, space, calib, mode, folder, effect=effect)
    hold = Calibrated(sim, space, holdout, mode, folder, fit.start_shifts(holdout), effect=effect)
    progress(f"      fitting {len(space.params)} nominal parameters of {space.name} on {len(calib)} run(s)")
    u, chosen, singles = fit_calibration(cal, max_nfev, progress, jobs)
    before, after = hold.gap(space.u0), hold.gap(u)
    alike = alike_values(cal, hold, singles, chosen[0], ALIKE_SHARE) if chosen else []
    other = held_out_first(cal, hold, singles, chosen, alike, after, max_nfev, jobs, progress) if alike else None
    if other is not None:
        u, chosen, after = other
        alike = alike_values(cal, hold, singles, chosen[0], ALIKE_SHARE)
    before_cal, after_cal = cal.gap(space.u0), cal.gap(u)
    shrink = shrink_pct(before, after)
    gate = fit.NOISE_GAIN * fit.noise_gap(holdout)
    accepted = shrink >= threshold and before - after >= gate
    alike = alike if accepted else []
    table = parameter_table(cal, u, chosen, accepted, carries_gain(hold, u, chosen, before, after) if accepted else {})
    moved = [p for p in table if p["moved"]]
    notes = [("not fitted: the config's value" if not p["chosen"] else
              ("moved" if p["moved"] else "fitted, not moved") + f": config {p['config']:.6g}, {p['change_pct']:+.1f}%, "
              f"95 % interval {p['interval'][0]:.6g}..{p['interval'][1]:.6g}"
              + ("" if p["identifiable"] else ", not identifiable from these logs")) for p in table]
    report = {
        "kept": bool(accepted),
        "why": (f"held-out gap {before:.3f} -> {after:.3f} ({shrink:+.1f}%), "
                + ("kept" if accepted else f"below the {threshold:.1f}% (and {gate:.3f} of gap) an explanation must "
                                     f"reach: not kept")),
        "parameters": table,
        "moved": [p["name"] for p in moved],
        "alike": alike,
        "calibration_gap": {"before": before_cal, "after": after_cal},
        "holdout_gap": {"before": before, "after": after},
        "shrink_pct": shrink,
        "simulations": cal.nsim + hold.nsim,
        "seconds": time.perf_counter() - t0,
        # every fitted value (the model the effects were fitted on), each with where it came from
        "ini": ini_text(config_file, space.name, space.params, [p["value"] for p in table], notes)
        if accepted else None,
    }
    report["handles"] = (cal, hold, u, chosen)     # for joint fits (pipeline.py); not written out
    report["config_file"] = cal.config(u) if accepted else config_file
    report["runs"] = (cal.runs_at(u), hold.runs_at(u)) if accepted else (list(calib), list(holdout))
    for p in table:
        if p["chosen"]:
            mark = "moved" if p["moved"] else ("not identifiable" if not p["identifiable"] else "not moved")
            progress(f"      {p['name']:<22} {p['config']:.4g} -> {p['value']:.4g} ({p['change_pct']:+.1f}%, "
                     f"95% {p['interval'][0]:.4g}..{p['interval'][1]:.4g}) {mark}")
    for a in alike:
        progress(f"      alike: {a['name']} {a['change_pct']:+.1f}% alone explains the held-out runs as well as "
                 f"{space.params[chosen[0]].name} alone ({a['holdout_gap']:.3f} against {a['first_holdout_gap']:.3f})")
    progress(f"      calibration: {report['why']}; {report['simulations']} simulations in {report['seconds']:.1f} s")
    return report


JOINT_NFEV = 20


def joint_fit(cal, hold, chosen, effect, u_effect, starts=(None,)):
    """An effect and the calibration's chosen values fitted together on the calibration
    runs, from the effect's own fit and each of `starts` (vectors of values; None is the
    config's), the best kept (fit._search): a real effect keeps its parameters and leaves
    the values near the config's; an effect standing in for a mis-set value gives way to
    it. From the calibration's values too, an effect fitted on the config as given is not
    held in the valley its stand-in role made (a friction hidden under a mis-set
    discharge coefficient). Returns {effect, params, u, calibration_gap, holdout_gap}."""
    d = len(effect.params)
    idx = list(chosen)

    def split(x):
        v = np.array(cal.space.u0, dtype=float)
        v[idx] = x[d:]
        return v, from_unit(effect, x[:d])

    def fun(x):
        v, params = split(x)
        p = cal.problem(v)
        r = p.residual_vector(effect.name, params)
        cal.nsim += p.nsim
        return np.concatenate([r, cal.space.prior(v)])
    cand = np.array([np.concatenate([np.asarray(u_effect, dtype=float),
                                     np.asarray(cal.space.u0 if s is None else s, dtype=float)[idx]])
                     for s in starts])
    cand = np.unique(cand, axis=0)
    x, _ = fit._search(fun, cand, JOINT_NFEV, len(cand), [float(np.sum(fun(c) ** 2)) for c in cand])
    v, params = split(x)
    hp = hold.problem(v)
    out = {"effect": effect.name, "params": params, "u": v,
           "calibration_gap": fit.cost_to_gap(fun(x)[:-len(v)], len(cal.runs)),
           "holdout_gap": hp.gap(effect.name, params)}
    hold.nsim += hp.nsim
    return out

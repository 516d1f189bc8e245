"""Fit each candidate effect on calibration runs, score it on held-out runs.

Parameters are fitted in a unit box (log-mapped where the range spans
decades) with scipy.optimize.least_squares and bounds. The on-off plant makes
the cost rough, so the cost is first evaluated at 32-128 quasi-random points (start_count, plus
the "off" point when it lies in the box) and least_squares polishes the best
four.
Candidates run in parallel processes, one simulator per process.

Pairs (two effects at once, "a+b"): one joint fit of both parameter lists,
started from the two single fits (and from the first's with the second off),
polished from both (pipeline.py and pairs.py decide which pairs and whether one is kept).
Screening fits of every partner of the leader are the same, polished briefly:
they rank the second effect; a full fit goes on from the best screened point.
"""
import os
import time
from dataclasses import replace
from concurrent.futures import ProcessPoolExecutor

import numpy as np
from scipy.optimize import least_squares
from scipy.stats import qmc

from . import effects as fx
from . import gap
from . import run_memo
from .effects import from_unit, to_unit
from .design import noise_levels
from .model import CLOSED_LOOP, REPLAY, make_simulator
from .uncertainty import assess, autocorrelation_inflation

RESAMPLE_S = 0.05        # residuals every 50 ms: 20 Hz is plenty for a 0.1-10 s plant
FAILED_RESIDUAL = 100.0  # normalised residual of a sample the simulation could not produce


def choose_mode(run, mode):
    if mode == "auto":
        return REPLAY if getattr(run, "has_commands", False) else CLOSED_LOOP
    return mode


class Problem:
    """Runs + simulator + mode: residual vectors for any (effect, params).

    start_shifts: [(height m, P2 Pa)] moves of the start state a log cannot
    resolve (held-out runs). Each run is then scored from the start among them
    (and its own) that fits best: on a platform held by hysteresis a move of one
    noise standard deviation decides when it breaks free, and a model must not
    win or lose on that luck. Calibration problems have none (a fit's cost would
    multiply by their number)."""

    def __init__(self, sim, config, runs, mode="auto", start_shifts=None):
        self.sim, self.config, self.runs, self.mode = sim, config, runs, mode
        self.start_shifts = list(start_shifts or [])
        self.nsim = 0

    def simulate(self, run, effect, params):
        self.nsim += 1
        return self.sim.simulate(self.config_of(run), run, effect, params, choose_mode(run, self.mode))

    def config_of(self, run):
        """The plant config a run is simulated with: its own, else the problem's."""
        return getattr(run, "config_override", None) or self.config

    def best_start(self, run, effect, params):
        """(trace, residuals) of the run from the start that fits best (start_shifts)."""
        tr = self.simulate(run, effect, params)
        res = run_residual(run, tr)
        if hasattr(run, "residual_vector") or not (self.start_shifts and self.sim.honours_start_shift):
            return tr, res
        for s in self.start_shifts:
            t2 = self.simulate(replace(run, start_shift=s), effect, params)
            r2 = run_residual(run, t2)
            if float(np.sum(r2 ** 2)) < float(np.sum(res ** 2)):
                tr, res = t2, r2
        return tr, res

    def residual_vector(self, effect, params):
        return np.concatenate([self.best_start(run, effect, params)[1] for run in self.runs])

    def cost_below(self, effect, params, bound):
        """The residual's sum of squares, as float(np.sum(residual_vector ** 2)), or
        None as soon as the runs simulated so far reach `bound`: the remaining runs
        are not simulated (a start or a grid point that cannot be among the best)."""
        parts, ss = [], 0.0
        for i, run in enumerate(self.runs):
            parts.append(self.best_start(run, effect, params)[1])
            ss += float(np.sum(parts[-1] ** 2))
            if ss >= bound and i < len(self.runs) - 1:
                return None
        return float(np.sum(np.concatenate(parts) ** 2))

    def gap(self, effect, params):
        return cost_to_gap(self.residual_vector(effect, params), len(self.runs))


def start_shifts(runs):
    """Moves of the start of a quarter and one standard deviation of the logs' own
    sensor noise in height and P2 (each sign, every combination): imperceptible in
    the quiet start the replay starts from."""
    noise = noise_levels(runs)
    sh, sp = noise.get("height_m", 2e-5), noise.get("p_spring_pa", 50.0)
    return [(h * sh, p * sp) for h in (-1.0, -0.25, 0.25, 1.0) for p in (-1.0, -0.25, 0.25, 1.0)]


# An explanation (a calibration, an effect, a pair) must lower the held-out gap by
# at least this share of the gap the logs' own sensor noise leaves: on a model
# already at the noise, a percentage of what is left is no evidence.
NOISE_GAIN = 0.5


def noise_gap(runs):
    """The gap a perfect model would leave on these runs: their sensor noise
    (design.noise_levels) in the gap's units (gap.SCALES, signals weighed alike)."""
    noise = noise_levels(runs)
    terms = [(noise[s] / gap.SCALES[s]) ** 2 for s in gap.SCALES if s in noise]
    return float(np.sqrt(np.mean(terms))) if terms else 0.0


def _residual_plan(run):
    """run_residual's stride and, per signal the run measures (gap.used_signals),
    the logged values (a view: run_memo makes it read-only, not the run's array)
    and where the strided samples are measured."""
    stride = max(1, int(round(RESAMPLE_S / float(np.median(np.diff(run.t_s))))))
    return stride, [(s, run.signals[s].view(), np.isfinite(run.signals[s][::stride])) for s in gap.used_signals(run)]


def run_residual(run, trace):
    """Normalised residuals of one run; each run weighs the same whatever its length."""
    if hasattr(run, "residual_vector"):          # a features run (features.py)
        return run.residual_vector(trace)
    stride, plan = run_memo.of_run(run, "residual", _residual_plan)
    parts = []
    for s, logged, measured in plan:
        sim = trace.signals.get(s)
        if sim is None:          # this simulator does not model the signal (gap.residuals)
            continue
        x = (sim - logged)[::stride] / gap.SCALES[s]
        # not measured: no information; measured but the simulation failed (NaN): as bad as it gets
        # a diverging simulation counts as failed, never as an overflow in the squares
        x = np.where(measured, np.where(np.isfinite(x), np.clip(x, -FAILED_RESIDUAL, FAILED_RESIDUAL),
                                        FAILED_RESIDUAL), 0.0)
        parts.append(x)
    if not parts:
        return np.zeros(0)
    v = np.concatenate(parts)
    return v / np.sqrt(len(v))      # sum of squares = mean normalised squared error


def cost_to_gap(r, nruns):
    """Normalised RMS gap averaged over runs from a stacked residual vector."""
    return float(np.sqrt(np.sum(r ** 2) / max(nruns, 1)))


def off_point(effect):
    """The nominal ("off") parameters in the unit box, or None when they lie outside it."""
    off = effect.nominal()
    return to_unit(effect, off) if all(p.lo <= off[p.name] <= p.hi for p in effect.params) else None


MAX_STARTS = 128   # quasi-random starts of a fit with 3 or more parameters


def start_count(d):
    """Starts for a d-parameter fit: 32 in 1-D, doubling per dimension up to
    MAX_STARTS. Basins can be narrow: with 32 starts in 3-D the nearest lies about
    0.15 of the box away, and a stick-slip friction fit polished from there stayed
    at half the calibration shrink the truth's values give (95 %, seen on an
    accumulator rig log); 128 found it."""
    return min(MAX_STARTS, 2 ** (d + 4))


def fit_effect(problem, effect, starts=None, max_nfev=60, seed=0, polish=4):
    """Least-squares fit of one effect. Returns dict with params, cost, evaluations."""
    if any(p.extends for p in effect.params):
        return fit_nested(problem, effect, starts, max_nfev, seed, polish)
    return fit_from(problem, effect, _starts(effect, range(len(effect.params)), starts, seed), max_nfev, polish)


def _starts(effect, idx, starts, seed):
    """Quasi-random starts over the parameters idx of the unit box, after the
    "off" point (nominal plant) when it lies in the box: a fit can always fall back to it."""
    sampler = qmc.Halton(len(idx), scramble=True, seed=seed)
    cand = sampler.random(max(2, starts or start_count(len(idx))))
    off = off_point(effect)
    return np.vstack([off[list(idx)], cand]) if off is not None else cand


PROBE_NFEV = 5    # evaluations that probe the whole box's best start of a nested fit


def fit_nested(problem, effect, starts=None, max_nfev=60, seed=0, polish=4):
    """An effect with extensions (effects.json `extends`): the base model first,
    the extensions at their nominal values (the very fit the base alone gets),
    then the whole model from the base's optimum. The best quasi-random start
    of the whole box is probed too, even when it starts higher (the extensions
    can open a basin the base's optimum does not lead to: a pipe of three
    segments, 0.72 from the base's optimum, 0.27 from the whole box's best
    start), with PROBE_NFEV evaluations, and polished on only when it is then
    the lower: a full polish of a start that leads nowhere cost 10 s. A start
    lower than the base's optimum is polished in full from the outset.
    Extensions cannot lose the base's fit, and the base's basins are not
    diluted in a box of more dimensions under the same budget."""
    d = len(effect.params)
    base = [i for i, p in enumerate(effect.params) if not p.extends]
    nominal = np.asarray(to_unit(effect, effect.nominal()), dtype=float)

    def embed(ub):
        u = nominal.copy()
        u[base] = ub
        return u

    fun, bounded = _residual(problem, effect), _bounded(problem, effect)
    ub, cost_b = _search(lambda ub: fun(embed(ub)), _starts(effect, base, starts, seed), max_nfev, polish,
                         bounded=lambda ub, bound: bounded(embed(ub), bound))
    u0 = embed(ub)
    whole = qmc.Halton(d, scramble=True, seed=seed).random(max(2, starts or start_count(d)))
    costs = start_costs(whole, bounded, 1)
    k = int(np.argmin(costs))
    u, cost = _search(fun, np.asarray([u0]), max_nfev, 1, [cost_b])
    probe = costs[k] >= cost_b and PROBE_NFEV < max_nfev    # a start under the base's: polished in full
    uw, cw = _search(fun, np.asarray([whole[k]]), PROBE_NFEV if probe else max_nfev, 1, [costs[k]])
    if probe and cw < cost:
        uw, cw = _search(fun, np.asarray([uw]), max_nfev, 1, [cw])
    if cw < cost:
        u, cost = uw, cw
    return _fit_result(problem, effect, u, cost)


def fit_from(problem, effect, cand, max_nfev=60, polish=4):
    """The cost at each start (rows of unit-box points), least_squares from the best `polish`."""
    u, cost = _search(_residual(problem, effect), cand, max_nfev, polish, bounded=_bounded(problem, effect))
    return _fit_result(problem, effect, u, cost)


def _residual(problem, effect):
    """The effect's residual vector as a function of a unit-box point."""
    return lambda u: problem.residual_vector(effect.name, from_unit(effect, u))


def _bounded(problem, effect):
    """The effect's sum of squares at a unit-box point, or None once it reaches a bound (Problem.cost_below)."""
    return lambda u, bound: problem.cost_below(effect.name, from_unit(effect, u), bound)


def _or_inf(cost):
    return float("inf") if cost is None else cost


def start_costs(cand, bounded, keep):
    """The cost of every start, exact for the `keep` lowest; a start whose first runs
    already cost more than the keep-th lowest so far is +inf (its last runs are not
    simulated). The keep lowest, their order and their costs are those of a full count."""
    costs, lowest = [], []
    for u in cand:
        bound = lowest[keep - 1] if len(lowest) >= keep else float("inf")
        c = _or_inf(bounded(u, bound))
        costs.append(c)
        if c < bound:
            lowest = sorted(lowest + [c])[:keep]
    return costs


def _search(fun, cand, max_nfev, polish, costs=None, bounded=None):
    """least_squares over the unit box from the `polish` lowest of the starts cand
    (their costs given, or costed here by `bounded`: start_costs); the best point and its cost."""
    d = cand.shape[1]
    if costs is None:
        costs = start_costs(cand, bounded, max(1, polish))
    order = np.argsort(costs)
    best_u, best_cost = cand[order[0]], costs[order[0]]
    for k in order[:polish]:
        try:
            res = least_squares(fun, cand[k], bounds=(np.zeros(d), np.ones(d)), diff_step=0.02,
                                x_scale=np.full(d, 0.3), max_nfev=max_nfev, method="trf")
        except ValueError:
            continue
        c = float(np.sum(res.fun ** 2))
        if c < best_cost:
            best_u, best_cost = res.x, c
    return best_u, best_cost


def _fit_result(problem, effect, u, cost):
    return {"params": from_unit(effect, u), "unit": [float(x) for x in u],
            "calibration_gap": float(np.sqrt(cost / max(len(problem.runs), 1)))}


def pair_starts(first, second, u_first, u_second):
    """Where a pair's joint fit starts: both single fits together, and the first's
    fit with the second at its nominal values, or as near them as the box allows
    (a leak of 1e-10 m^2, undelayed valves): from there the joint fit can fall
    back to the first alone."""
    return np.array([np.concatenate([u_first, u_second]),
                     np.concatenate([u_first, to_unit(second, second.nominal())])])


def residual_samples(problem, effect, params):
    """Sum of squares of the residuals and their effective number of
    independent samples (n shrunk by the lag-1 autocorrelation, as the intervals do)."""
    r = problem.residual_vector(effect, params)
    return float(np.sum(r ** 2)), len(r) / autocorrelation_inflation(r)


# --- parallel candidates ----------------------------------------------------------

_worker = {}


def _init_worker(spec, config, calib, holdout, mode):
    sim = make_simulator(spec)
    _worker["calib"] = Problem(sim, config, calib, mode)
    _worker["hold"] = Problem(sim, config, holdout, mode, start_shifts(holdout))


def _run_candidate(name, fit_opts):
    t0 = time.perf_counter()
    eff = fx.get(name)
    calib, hold = _worker["calib"], _worker["hold"]
    res = fit_effect(calib, eff, **fit_opts)
    res["holdout_gap"] = hold.gap(name, res["params"])
    res["uncertainty"] = assess(calib, eff, res["unit"])
    res["simulations"] = calib.nsim + hold.nsim
    res["seconds"] = time.perf_counter() - t0
    calib.nsim = hold.nsim = 0
    return name, res


PAIR_NFEV = 40   # least_squares evaluations of a pair's joint fit, from each of its two starts
SCREEN_NFEV = 6   # a screening fit's evaluations, from each start


def _run_pair(name, starts, fit_opts, screen=False):
    """Joint fit of a pair "a+b" from its starts; held-out gap, intervals (no
    refits over runs: a pair is judged on its held-out gain), residual samples.
    A screening fit (screen) is brief and has no intervals: it ranks the
    partners of the leader, it does not name one."""
    t0 = time.perf_counter()
    eff = fx.get(name)
    calib, hold = _worker["calib"], _worker["hold"]
    nfev = min(SCREEN_NFEV if screen else PAIR_NFEV, fit_opts.get("max_nfev", PAIR_NFEV))
    # from both starts: the leader's single fit has taken up part of the second
    # effect, and from there the joint fit can stay in that valley (seen on the
    # stand-in plant's leak + lagging offset reading)
    res = fit_from(calib, eff, np.asarray(starts), nfev, polish=len(starts))
    res["uncertainty"] = {} if screen else assess(calib, eff, res["unit"], resample=False)
    res["calibration_ss"], res["calibration_n_eff"] = residual_samples(calib, name, res["params"])
    res["holdout_ss"], res["holdout_n_eff"] = residual_samples(hold, name, res["params"])
    res["holdout_gap"] = float(np.sqrt(res["holdout_ss"] / max(len(hold.runs), 1)))
    res["simulations"] = calib.nsim + hold.nsim
    res["seconds"] = time.perf_counter() - t0
    calib.nsim = hold.nsim = 0
    return name, res


def _cost(name):
    """A fit's expected cost, for the order of submission: its parameters (a pair's
    both); line_delay's eight and RK4 substeps make it the longest by far."""
    return sum(len(fx.get(n).params) for n in fx.parts(name))


def _in_pool(spec, config, calib, holdout, mode, jobs, work, progress):
    """Runs work [(fn, args)] (args[0]: the effect's name) in parallel processes (or
    here with jobs 1). The longest fits are submitted first, so that one does not
    start last and keep the other process idle; results and progress keep the
    order of work. Returns {name: result}."""
    out = {}
    if jobs <= 1:
        _init_worker(spec, config, calib, holdout, mode)
        for fn, args in work:
            n, r = fn(*args)
            out[n] = r
            if progress:
                progress(n, r)
        return out
    with ProcessPoolExecutor(max_workers=jobs, initializer=_init_worker,
                             initargs=(spec, config, calib, holdout, mode)) as pool:
        order = sorted(range(len(work)), key=lambda i: -_cost(work[i][1][0]))
        futs = {i: pool.submit(work[i][0], *work[i][1]) for i in order}
        for f in (futs[i] for i in range(len(work))):
            n, r = f.result()
            out[n] = r
            if progress:
                progress(n, r)
    return out


def fit_all(spec, config, calib, holdout, mode="auto", candidates=None, jobs=None, progress=None,
            fit_opts=None):
    """Fit every candidate (in parallel processes). Returns {name: result}."""
    candidates = candidates or fx.NAMES
    fit_opts = fit_opts or {}
    jobs = jobs or min(len(candidates), os.cpu_count() or 1, 2)
    return _in_pool(spec, config, calib, holdout, mode, jobs,
                    [(_run_candidate, (name, fit_opts)) for name in candidates], progress)


def fit_pairs(spec, config, calib, holdout, pairs, mode="auto", jobs=None, progress=None, fit_opts=None,
              screen=False):
    """Joint fits of pairs {"a+b": starts} (pair_starts), or screening fits. Returns {name: result}."""
    if not pairs:
        return {}
    jobs = jobs or min(len(pairs), os.cpu_count() or 1, 2)
    return _in_pool(spec, config, calib, holdout, mode, jobs,
                    [(_run_pair, (name, st, fit_opts or {}, screen)) for name, st in pairs.items()], progress)

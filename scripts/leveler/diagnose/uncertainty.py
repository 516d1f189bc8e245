"""How sure: an interval for every fitted parameter, flags for "at its bound" and
"not identifiable from these logs", and a check of the intervals by refitting
on the runs left after dropping one (a bootstrap over runs; with two runs it is
the jackknife, the only resampling two runs allow).

The interval is the Jacobian's: cov = s^2 (J^T J)^-1 in the fit's unit box,
s^2 the residual variance, inflated by the residuals' lag-1 autocorrelation
(a 20 Hz residual of a 0.1-10 s plant is far from white: without it the
intervals would be several times too narrow). It is mapped to physical units
through the box (log-mapped parameters get asymmetric intervals).
"""
import numpy as np
from scipy.optimize import least_squares

from .effects import from_unit

Z95 = 1.96
STEP = 0.01               # finite-difference step in the unit box
UNIDENTIFIABLE_SD = 0.25  # a 95 % interval wider than the whole range
BOUND_TOL = 1e-3          # unit-box distance that counts as "at its bound"


def jacobian(fun, u, step=STEP):
    """Forward differences (backward at the upper edge) of the residual vector."""
    r0 = fun(u)
    J = np.empty((len(r0), len(u)))
    for j in range(len(u)):
        h = step if u[j] + step <= 1.0 else -step
        uu = np.array(u, dtype=float)
        uu[j] += h
        J[:, j] = (fun(uu) - r0) / h
    return r0, J


def autocorrelation_inflation(r):
    """(1 + rho) / (1 - rho) for the lag-1 autocorrelation rho of the residuals."""
    den = float(np.sum(r * r))
    if den <= 0.0 or len(r) < 3:
        return 1.0
    rho = float(np.clip(np.sum(r[1:] * r[:-1]) / den, 0.0, 0.98))
    return (1.0 + rho) / (1.0 - rho)


def unit_covariance(r, J):
    """Covariance of the unit-box parameters, and which directions the data do not see."""
    m, d = J.shape
    s2 = float(np.sum(r * r)) / max(m - d, 1) * autocorrelation_inflation(r)
    jtj = J.T @ J
    blind = np.diag(jtj) <= 1e-12 * max(float(np.max(np.diag(jtj))), 1e-300)
    return s2 * np.linalg.pinv(jtj, rcond=1e-10), blind


def intervals(problem, effect, u):
    """{param: {interval, sd_unit, at_bound, identifiable}} at the fitted point u."""
    fun = lambda x: problem.residual_vector(effect.name, from_unit(effect, x))
    r, J = jacobian(fun, np.asarray(u, dtype=float))
    cov, blind = unit_covariance(r, J)
    out = {}
    for j, p in enumerate(effect.params):
        sd = float(np.sqrt(max(cov[j, j], 0.0))) if not blind[j] else float("inf")
        lo_u = np.array(u, dtype=float)
        hi_u = np.array(u, dtype=float)
        lo_u[j] = max(0.0, u[j] - Z95 * sd) if np.isfinite(sd) else 0.0
        hi_u[j] = min(1.0, u[j] + Z95 * sd) if np.isfinite(sd) else 1.0
        out[p.name] = {
            "interval": [from_unit(effect, lo_u)[p.name], from_unit(effect, hi_u)[p.name]],
            "sd_unit": sd,
            "at_bound": bool(u[j] <= BOUND_TOL or u[j] >= 1.0 - BOUND_TOL),
            "identifiable": bool(np.isfinite(sd) and sd < UNIDENTIFIABLE_SD),
        }
    return out


def over_runs(problem, effect, u, max_nfev=15):
    """Refit from u on the runs left after dropping each one in turn: the spread a
    different set of runs gives. Empty with a single run."""
    runs = list(problem.runs)
    if len(runs) < 2:
        return []
    d = len(u)
    out = []
    for k in range(len(runs)):
        sub = type(problem)(problem.sim, problem.config, runs[:k] + runs[k + 1:], problem.mode)
        fun = lambda x: sub.residual_vector(effect.name, from_unit(effect, x))
        try:
            res = least_squares(fun, np.asarray(u, dtype=float), bounds=(np.zeros(d), np.ones(d)),
                                diff_step=0.02, x_scale=np.full(d, 0.3), max_nfev=max_nfev, method="trf")
            out.append(from_unit(effect, res.x))
        except ValueError:
            continue
        problem.nsim += sub.nsim
    return out


def assess(problem, effect, u, resample=True):
    """Intervals, flags and the check over runs: a refit on fewer runs that lands
    outside the Jacobian interval says the interval is too narrow."""
    iv = intervals(problem, effect, u)
    refits = over_runs(problem, effect, u) if resample else []
    for name, e in iv.items():
        vals = [r[name] for r in refits]
        e["over_runs"] = vals
        lo, hi = e["interval"]
        span = max(hi - lo, 0.0)
        e["over_runs_within"] = bool(all(lo - 0.05 * span <= v <= hi + 0.05 * span for v in vals))
    return iv

"""The starts of a fit are costed run by run and a start stops being simulated once
its first runs cost more than it could to be kept (fit.start_costs,
Problem.cost_below): the kept starts, their order, their costs and the fit that
follows must be those of the full count, which each test also makes."""
import numpy as np

from conftest import thesis_schedule
from leveler.diagnose import fit
from leveler.diagnose import effects as fx
from leveler.diagnose.model import REPLAY
from leveler.diagnose.runs import Run

CONFIG = "thesis-900lb"


def leak_runs(cplant, n=3):
    """Closed-loop runs of the C plant with a leak, a little noise on each: the logs."""
    rng = np.random.default_rng(7)
    out = []
    for k in range(n):
        t, load = thesis_schedule(end=30.0, on=5.0, off=20.0, step_lb=150.0 + 50.0 * k)
        tr = cplant._closed_loop(CONFIG, t, load, 6, [3e-8], [np.nan] * 4 + [0.0])
        sig = {s: v + (rng.normal(0.0, 2e-5 if s == "height_m" else 300.0, len(v)) if s != "p_acc_pa" else 0.0)
               for s, v in tr.signals.items()}
        out.append(Run(f"leak{k}.csv", t, sig, load, tr.commands))
    return out


def test_cost_below_is_the_full_sum_or_stops_after_the_runs_that_reach_the_bound(cplant):
    prob = fit.Problem(cplant, CONFIG, leak_runs(cplant), REPLAY)
    params = {"leak_area_m2": 1e-7}
    full = float(np.sum(prob.residual_vector("leak", params) ** 2))
    per_run = [float(np.sum(fit.run_residual(r, prob.simulate(r, "leak", params)) ** 2)) for r in prob.runs]
    prob.nsim = 0
    assert prob.cost_below("leak", params, float("inf")) == full     # bit for bit: the same sum
    assert prob.nsim == 3
    prob.nsim = 0
    assert prob.cost_below("leak", params, 0.5 * per_run[0]) is None  # the first run alone reaches it
    assert prob.nsim == 1
    prob.nsim = 0
    assert prob.cost_below("leak", params, per_run[0] + 0.5 * per_run[1]) is None
    assert prob.nsim == 2
    # the last run is always simulated: the answer is then the cost itself, whatever the bound
    prob.nsim = 0
    assert prob.cost_below("leak", params, per_run[0] + per_run[1] + 0.5 * per_run[2]) == full
    assert prob.nsim == 3


def test_start_costs_keep_the_lowest_starts_of_the_full_count(cplant):
    prob = fit.Problem(cplant, CONFIG, leak_runs(cplant), REPLAY)
    eff = fx.get("leak")
    cand = fit._starts(eff, range(1), 24, seed=3)
    full = [float(np.sum(fit._residual(prob, eff)(u) ** 2)) for u in cand]
    prob.nsim = 0
    costs = fit.start_costs(cand, fit._bounded(prob, eff), keep=4)
    assert prob.nsim < 3 * len(cand)                               # some starts stopped early
    low = np.argsort(full)[:4]
    assert list(np.argsort(costs)[:4]) == list(low)
    assert [costs[i] for i in low] == [full[i] for i in low]
    assert all(c >= full[low[-1]] for i, c in enumerate(costs) if i not in low)


def test_a_fit_with_bounded_starts_is_the_fit_of_the_full_count(cplant):
    prob = fit.Problem(cplant, CONFIG, leak_runs(cplant), REPLAY)
    eff = fx.get("leak")
    cand = fit._starts(eff, range(1), 16, seed=5)
    fun = fit._residual(prob, eff)
    full = [float(np.sum(fun(u) ** 2)) for u in cand]   # every start costed in full
    u_full, c_full = fit._search(fun, cand, 20, 2, costs=full)
    n_full, prob.nsim = prob.nsim, 0
    u_b, c_b = fit._search(fun, cand, 20, 2, bounded=fit._bounded(prob, eff))
    assert c_b == c_full and np.array_equal(u_b, u_full)
    assert prob.nsim < n_full

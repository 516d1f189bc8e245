"""fit.fit_nested on a problem whose residual is a formula: one base parameter x and
one extension y (nominal 0). In y the cost has a local minimum at the nominal 0
and a lower one at y = 0.8 behind a ridge; in x a narrow valley at 0.3, so every
quasi-random start of the whole box costs more than the base's optimum (0.3, 0),
while the best of them lies in the lower basin. A nested fit must reach it:
polishing only from the base's optimum, or only from starts under its cost,
stays at the nominal's 0.25."""
import numpy as np
import pytest

from leveler.diagnose import fit
from leveler.diagnose.effects import Effect, Param

EFFECT = Effect("formula", 0, (Param("x", 0.0, 1.0, 0.5), Param("y", 0.0, 1.0, 0.0, extends=True)), "")
K = 30.0    # the x valley's steepness: no start of the whole box lies in it


def residual(x, y):
    lower = 0.5 * np.exp(-((y - 0.8) / 0.2) ** 2)      # the basin behind the ridge: r = 0.4 there
    rise = 0.4 * (1.0 - np.exp(-(y / 0.2) ** 2))        # out of the nominal's basin: r = 0.5 there
    return np.array([K * (x - 0.3), 0.5 - lower + rise])


class FormulaProblem:
    """What fit_nested asks of a Problem, for one run: residuals and bounded costs."""

    def __init__(self):
        self.runs, self.nsim = [None], 0

    def residual_vector(self, effect, params):
        self.nsim += 1
        return residual(params["x"], params["y"])

    def cost_below(self, effect, params, bound):
        return float(np.sum(self.residual_vector(effect, params) ** 2))


def cost(x, y):
    return float(np.sum(residual(x, y) ** 2))


def test_the_formula_is_the_case_it_stands_for():
    whole = fit.qmc.Halton(2, scramble=True, seed=0).random(fit.start_count(2))
    costs = [cost(*u) for u in whole]
    best = whole[int(np.argmin(costs))]
    assert min(costs) > cost(0.3, 0.0)             # every start of the whole box costs more
    assert abs(best[1] - 0.8) < 0.2                # and the best lies in the lower basin
    assert cost(0.3, 0.8) == pytest.approx(0.16, abs=1e-6)
    assert cost(0.3, 0.0) == pytest.approx(0.25, abs=1e-6)


def test_the_nested_fit_reaches_the_basin_only_the_whole_box_leads_to():
    prob = FormulaProblem()
    res = fit.fit_nested(prob, EFFECT)
    assert res["params"]["x"] == pytest.approx(0.3, abs=1e-3)
    assert res["params"]["y"] == pytest.approx(0.8, abs=0.01)
    assert res["calibration_gap"] ** 2 == pytest.approx(0.16, abs=1e-3)


class NoLowerBasin(FormulaProblem):
    def residual_vector(self, effect, params):
        self.nsim += 1
        y = params["y"]     # a rippled slope up from the nominal: no lower basin, a long way down
        return np.array([K * (params["x"] - 0.3), 0.5 + 0.3 * y + 0.05 * np.sin(20.0 * y) ** 2])


def test_a_probe_that_leads_nowhere_is_cut_short_and_loses_nothing(monkeypatch):
    """Without the lower basin the whole box's best start is polished for PROBE_NFEV
    evaluations only (with their finite differences): fewer residuals than its full
    polish, and the base's fit stands."""
    probed = NoLowerBasin()
    res = fit.fit_nested(probed, EFFECT)
    assert res["calibration_gap"] ** 2 == pytest.approx(0.25, abs=1e-6)
    assert res["params"]["y"] < 0.01
    monkeypatch.setattr(fit, "PROBE_NFEV", 60)     # no probe: the start polished in full
    full = NoLowerBasin()
    assert fit.fit_nested(full, EFFECT)["calibration_gap"] == res["calibration_gap"]
    assert probed.nsim < full.nsim

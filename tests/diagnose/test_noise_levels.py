"""The logs' own noise (design.noise_levels), against the error a perfect model would
leave on a converter's counts: the sensor noise and the rounding to the count, drawn
here with a fixed seed and measured directly."""
import numpy as np

from leveler.diagnose import design
from leveler.diagnose.runs import Run

COUNT_PA = 1350.0       # a coarse pressure converter's count (the blind test's rig logs)


def _run(sigma_pa, n=2000, seed=1):
    """A platform at rest, P2 around 300 kPa read through noise and a converter."""
    rng = np.random.default_rng(seed)
    true = 300e3 + 0.3 * COUNT_PA * np.sin(np.linspace(0.0, 6.0, n))     # a slow drift within a count or so
    read = np.round((true + rng.normal(0.0, sigma_pa, n)) / COUNT_PA) * COUNT_PA
    nan = np.full(n, np.nan)
    signals = {"height_m": nan, "p_spring_pa": read, "p_pipe_pa": nan, "p_acc_pa": nan}
    return Run("hold.csv", np.arange(n) * 0.02, signals, np.zeros(n)), float(np.sqrt(np.mean((read - true) ** 2)))


def test_counts_repeating_in_most_samples_keep_the_rounding_error():
    # noise a sixth of a count: most successive readings repeat, the median deviation is nothing
    run, error = _run(COUNT_PA / 6.0)
    d = np.diff(run.signals["p_spring_pa"])
    assert np.mean(d == 0.0) > 0.5
    est = design.noise_levels([run])["p_spring_pa"]
    assert est >= COUNT_PA / np.sqrt(12.0) - 1e-9
    assert error / 2.0 < est < 2.0 * error      # the error a perfect model leaves, within a factor of two


def test_either_side_of_half_the_counts_repeating_the_estimates_stay_near_the_error():
    # noise either side of where half the successive counts repeat: the median deviation
    # jumps from one count to nothing there; the estimates stay within a factor of two of
    # the error a perfect model leaves, and four of each other (28 times with the floor)
    runs = [_run(s * COUNT_PA) for s in (0.45, 0.6)]
    repeats = [np.mean(np.diff(r.signals["p_spring_pa"]) == 0.0) for r, _ in runs]
    assert repeats[0] > 0.5 > repeats[1]
    levels = [design.noise_levels([r])["p_spring_pa"] for r, _ in runs]
    for level, (_, error) in zip(levels, runs):
        assert error / 2.0 < level < 2.0 * error
    assert max(levels) / min(levels) < 4.0

"""leveler.events on synthetic logs whose answers are known by construction."""

import numpy as np
import pytest

import synth
from leveler import events, thesis

# How close each figure must come, clean and noisy (SI).
CLEAN = {"m": 1e-6, "pa": 1.0, "s": 1e-3}
# Noise 0.3 mm / 2 kPa (about 0.3 psi), 0.08 mm ADC steps: 0.004 in, 0.4 psi, 0.15 s.
NOISY = {"m": thesis.in_to_m(0.004), "pa": thesis.psia_to_pa(0.4), "s": 0.15}


def tolerance(key, tol):
    return tol["m"] if key.endswith("_m") else tol["pa"] if key.endswith("_pa") else tol["s"]


def check(summary, tol):
    want = synth.expected()
    assert set(summary) == set(events.SUMMARY_KEYS)
    for key, value in want.items():
        assert summary[key] == pytest.approx(value, abs=tolerance(key, tol)), key


def test_clean_log_gives_the_constructed_figures():
    check(events.summarize(synth.make_log()), CLEAN)


def test_coarse_sampling_still_exact_at_the_corners():
    # 10 Hz: corners fall on samples, the tolerance extension removes the bias.
    check(events.summarize(synth.make_log(dt=0.1)), CLEAN)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_noisy_quantised_log(seed):
    log = synth.make_log(height_noise_m=0.3e-3, p_noise_pa=2000.0, height_quantum_m=0.08e-3,
                         seed=seed)
    check(events.summarize(log), NOISY)


def test_noise_and_quantum_estimates():
    log = synth.make_log(height_noise_m=0.3e-3, height_quantum_m=0.08e-3, seed=4)
    a = events.analyze(log)
    assert a.noise_sigma_m == pytest.approx(0.3e-3, rel=0.25)
    assert a.quantum_m == pytest.approx(0.08e-3, rel=1e-6)
    clean = events.analyze(synth.make_log())
    assert clean.noise_sigma_m == 0.0


def test_spikes_do_not_move_the_extremes():
    log = synth.make_log()
    log.height_m[1500] -= 0.02      # a 20 mm one-sample glitch while stuck at the bottom
    log.height_m[4000] += 0.02      # and one while stuck at the top
    log.p_spring_pa[2138] += 5e4    # a pressure spike just before break-away (21.38 s)
    s = events.summarize(log)
    assert s["p2_breakaway_pa"] == pytest.approx(thesis.psia_to_pa(105.0), abs=1.0)
    assert s["lowest_height_m"] == pytest.approx(thesis.in_to_m(14.53), abs=1e-4)
    assert s["highest_height_m"] == pytest.approx(thesis.in_to_m(17.54), abs=1e-4)


def test_load_events_from_load_column():
    log = synth.make_log()
    ev = events.find_load_events(log.t_s, log.load_n)
    assert [round(e.t_s, 6) for e in ev] == [5.0, 35.0]
    assert ev[0].delta_n == pytest.approx(thesis.lb_to_n(200.0))
    assert ev[1].delta_n == pytest.approx(-thesis.lb_to_n(200.0))


def test_ramped_load_placement_is_one_event():
    t = np.arange(0.0, 10.0, 0.01)
    load = np.interp(t, [0, 5.0, 5.5, 10], [4000, 4000, 4890, 4890])   # placed over 0.5 s
    ev = events.find_load_events(t, load)
    assert len(ev) == 1
    assert ev[0].t_s == pytest.approx(5.01, abs=0.011)
    assert ev[0].after_n == pytest.approx(4890)


def test_small_load_changes_are_not_events():
    t = np.arange(0.0, 10.0, 0.01)
    load = 4000 + 20.0 * (t > 5)
    assert events.find_load_events(t, load) == []


def test_undefined_figures_are_none():
    # The log stops at 30 s, still climbing; no removal.
    s = events.summarize(synth.make_log(end=26.0))
    assert s["time_return_after_step_s"] is None and s["p2_after_climb_pa"] is None
    assert s["time_stuck_bottom_s"] == pytest.approx(16.0, abs=1e-3)
    for key in ("highest_height_m", "p2_jump_pa", "time_stuck_top_s", "p2_start_down_pa",
                "time_return_after_removal_s"):
        assert s[key] is None
    # Still at the bottom when the log ends: no break-away, no stuck time.
    s = events.summarize(synth.make_log(end=15.0))
    assert s["time_stuck_bottom_s"] is None and s["p2_breakaway_pa"] is None
    assert s["lowest_height_m"] == pytest.approx(thesis.in_to_m(14.53), abs=1e-6)
    # No load change at all.
    log = synth.make_log(end=4.0)
    assert all(v is None for v in events.summarize(log).values())


def test_rig_without_spring_pressure():
    log = synth.make_log()
    log.p_spring_pa[:] = np.nan
    s = events.summarize(log)
    assert s["p2_drop_stop_pa"] is None and s["p2_breakaway_pa"] is None
    assert s["time_stuck_bottom_s"] == pytest.approx(16.0, abs=1e-3)


def test_band_from_options_moves_the_return_time():
    log = synth.make_log()
    lower = thesis.in_to_m(15.0)
    s = events.summarize(log, events.EventOptions(band_lower_m=lower))
    want = 21.4 + (15.0 - 14.53) / (15.70 - 14.53) * 8.6 - 5.0
    assert s["time_return_after_step_s"] == pytest.approx(want, abs=1e-3)


def test_duck_typed_log_is_enough():
    # leveler.diagnose passes a namespace with just these four arrays.
    from types import SimpleNamespace
    log = synth.make_log()
    s = events.summarize(SimpleNamespace(t_s=log.t_s, height_m=log.height_m,
                                         p_spring_pa=log.p_spring_pa, load_n=log.load_n))
    check(s, CLEAN)

"""Phase split of a synthetic run whose phase boundaries are known by construction."""
import numpy as np

from leveler.diagnose import phases

# (phase, start s, end s, height at end mm); the platform path is piecewise linear
PATH = [("steady", 0.0, 5.0, 397.5), ("drop", 5.0, 7.0, 370.0), ("stuck_low", 7.0, 20.0, 370.0),
        ("climb", 20.0, 25.0, 397.5), ("settle", 25.0, 35.0, 397.5), ("jump", 35.0, 37.0, 445.0),
        ("stuck_high", 37.0, 45.0, 445.0), ("return", 45.0, 47.0, 400.0), ("settle", 47.0, 55.0, 400.0)]


def synthetic(noise_mm=0.08, seed=0):
    t = np.round(np.arange(0.0, 55.0, 0.01), 2)
    knots_t = [0.0] + [p[2] for p in PATH]
    knots_h = [397.5] + [p[3] for p in PATH]
    h = np.interp(t, knots_t, knots_h) * 1e-3
    h += np.random.default_rng(seed).normal(0.0, noise_mm * 1e-3, len(t))
    load = np.where((t >= 5.0) & (t < 35.0), 4893.0, 4003.4)
    return t, h, load


def test_phases_found_where_they_were_made():
    t, h, load = synthetic()
    labels = phases.split(t, h, load)
    spans = phases.spans(t, labels)
    assert [s[0] for s in spans] == [p[0] for p in PATH]
    for (name, t0, t1), (want, w0, w1, _) in zip(spans, PATH):
        # the edges of "stuck" are where the platform comes within the rest tolerance:
        # a fraction of a second from the kink of the constructed path
        assert abs(t0 - w0) < 0.35, (name, t0, w0)
        assert abs(t1 - w1) < 0.35, (name, t1, w1)


def test_no_motion_after_a_load_change_is_settle():
    t, h, load = synthetic()
    flat = np.full(len(t), 0.3975) + np.random.default_rng(1).normal(0, 0.08e-3, len(t))
    labels = phases.split(t, flat, load)
    assert set(labels[t >= 5.0]) == {"settle"}
    assert set(labels[t < 5.0]) == {"steady"}

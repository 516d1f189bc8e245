"""Synthetic run logs from known piecewise-linear trajectories.

The trajectory is the thesis's 900 lb story with round numbers, so every
event figure is known by construction (see ``expected``). Knots are in thesis
units (s, in, psia) and converted to SI.
"""

import numpy as np

from leveler import runlog, thesis

# (t_s, height_in, p2_psia)
KNOTS = [
    (0.0, 15.65, 89.0),
    (5.0, 15.65, 89.0),     # +200 lb at 5 s
    (5.4, 14.53, 96.0),     # drop ends: rest at the bottom (B)
    (21.4, 14.53, 105.0),   # 16 s later: break-away (C)
    (30.0, 15.70, 101.0),   # climb ends in the band (D)
    (35.0, 15.70, 101.0),   # -200 lb at 35 s
    (35.3, 17.54, 84.0),    # jump ends: rest at the top (F)
    (42.8, 17.54, 74.0),    # 7.5 s later: starts down (G)
    (46.0, 15.75, 89.0),    # back in the band (H)
    (55.0, 15.75, 89.0),
]
STEP_T, REMOVAL_T = 5.0, 35.0
BASE_LB, STEP_LB = 900.0, 200.0


def _cross(t0, h0, t1, h1, level):
    return t0 + (level - h0) / (h1 - h0) * (t1 - t0)


def expected():
    """Event figures by construction (SI)."""
    return {
        "height_before_step_m": thesis.in_to_m(15.65),
        "lowest_height_m": thesis.in_to_m(14.53),
        "p2_drop_stop_pa": thesis.psia_to_pa(96.0),
        "time_stuck_bottom_s": 16.0,
        "p2_breakaway_pa": thesis.psia_to_pa(105.0),
        "time_return_after_step_s": _cross(21.4, 14.53, 30.0, 15.70, 15.6) - STEP_T,
        "p2_after_climb_pa": thesis.psia_to_pa(101.0),
        "highest_height_m": thesis.in_to_m(17.54),
        "p2_jump_pa": thesis.psia_to_pa(84.0),
        "time_stuck_top_s": 7.5,
        "p2_start_down_pa": thesis.psia_to_pa(74.0),
        "time_return_after_removal_s": _cross(42.8, 17.54, 46.0, 15.75, 15.8) - REMOVAL_T,
    }


def make_log(dt=0.01, height_noise_m=0.0, p_noise_pa=0.0, height_quantum_m=0.0,
             seed=1, end=55.0, config="thesis-900lb", source="sim"):
    rng = np.random.default_rng(seed)
    t = np.round(np.arange(0.0, end + dt / 2, dt), 9)
    kt = np.array([k[0] for k in KNOTS])
    h = thesis.in_to_m(np.interp(t, kt, [k[1] for k in KNOTS]))
    p2 = thesis.psia_to_pa(np.interp(t, kt, [k[2] for k in KNOTS]))
    if height_noise_m:
        h = h + rng.normal(0.0, height_noise_m, len(t))
    if height_quantum_m:
        h = np.round(h / height_quantum_m) * height_quantum_m
    if p_noise_pa:
        p2 = p2 + rng.normal(0.0, p_noise_pa, len(t))
    load = np.where((t >= STEP_T) & (t < REMOVAL_T), BASE_LB + STEP_LB, BASE_LB)
    load = thesis.lb_to_n(load)
    h_in = thesis.m_to_in(h)
    below = h_in < 15.6
    above = h_in > 15.8
    compressor = below.astype(float)
    solenoid = (below | above).astype(float)
    vent = above.astype(float)
    p1 = np.where(solenoid > 0, p2 + 2000.0, thesis.psia_to_pa(89.0))
    return runlog.RunLog.from_arrays(
        t, h, load, p_spring_pa=p2, p_pipe_pa=p1, p_acc_pa=None,
        compressor=compressor, spring_valve=solenoid, vent_valve=vent, acc_valve=0.0,
        config=config, source=source)

"""The thesis 900 lb rig through the leveler package that imports here (the
installed one, or the checkout's with PYTHONPATH=scripts): printed as JSON.

From rest with the blind test's truth library and no effect (libleveler_truth.so),
40 s at the config's base load with 240 lb more from 5 s to 25 s (the blind
test's first calibration step); then that
run replayed closed loop by the diagnosis's C plant (libleveler_diag.so), and
the config's band edges as leveler-sim --dump-config gives them."""
import json

import numpy as np

from leveler import config, engine, paths
from leveler.diagnose import cplant, model, runs

NAME = "thesis-900lb"
LB_N = 4.4482216152605

sim = model.make_simulator()
sim.check_config(NAME)                    # the name, resolved in cplant.CONFIG_DIR, checked by the C loader
cfg = config.load(cplant.config_path(NAME))
t = np.round(np.arange(0.0, 40.0 + 1e-9, engine.tick_s()), 2)
load = np.where((t >= 5.0) & (t < 25.0), cfg.base_load_n + 240 * LB_N, cfg.base_load_n)
truth = sim.generate(NAME, t, load, None, None)
run = runs.Run(path="truth", t_s=t, signals=truth.signals, load_n=load, commands=truth.commands)
replay = sim.simulate(NAME, run, None, {}, model.CLOSED_LOOP)
h = truth.signals["height_m"]
print(json.dumps({
    "package": paths.PACKAGE, "checkout": paths.ROOT, "config_dir": cplant.CONFIG_DIR,
    "diag_lib": engine.find_library(), "truth_lib": engine.find_truth_library(), "sim": config.find_sim(),
    "band_m": [cfg.band_lower_m, cfg.band_upper_m],
    "height_start_m": float(h[0]), "height_min_m": float(h.min()), "height_at_25s_m": float(h[t == 25.0][0]),
    "height_end_m": float(h[-1]),
    "replay_height_end_m": float(replay.signals["height_m"][-1]),
    "compressor_on_ticks": int(np.sum(truth.commands["compressor"])),
    "compressor_on_loaded_ticks": int(np.sum(truth.commands["compressor"][(t >= 5.0) & (t < 25.0)])),
}))

"""The PIL harness's plant (the engine's stepping API) runs the config's
[effect.NAME] sections: driven tick for tick with the actuators leveler-sim's
firmware chose for the same config, it follows leveler-sim's plant state (the
log's true_* columns) to the log's digits. No image needed."""
import os
import subprocess

import numpy as np

from leveler import runlog
from leveler_pil.plant import Plant

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def test_the_pil_plant_runs_the_configs_effect(tmp_path):
    cfg = tmp_path / "slow-valves.ini"
    cfg.write_text(f"[config]\ninclude = {ROOT}/host_sim/configs/thesis-900lb.ini\nname = slow-valves\n\n"
                   "[scenario]\nend_s = 20\n\n[effect.valve_dynamics]\nopen_delay_s = 0.1\nclose_delay_s = 0.04\n")
    log_path = tmp_path / "sim.csv"
    p = subprocess.run([os.environ["LEVELER_SIM"], "--config", str(cfg), "--log", str(log_path), "--quiet"],
                       capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    log = runlog.read(str(log_path))
    cmds = np.stack([np.asarray(log.column(c), dtype=int) for c in
                     ("compressor", "spring_valve", "vent_valve", "acc_valve")], axis=1)
    plant = Plant(cfg)
    states = np.array([plant.step(cmds[k])[0] for k in range(len(cmds))])
    h = np.asarray(log.column("true_height_m"), dtype=float)
    p2 = np.asarray(log.column("true_p_spring_pa"), dtype=float)
    assert np.max(np.abs(states[:, 1] - h)) < 2e-9
    assert np.max(np.abs(states[:, 2] - p2)) < 2e-3
    # and the effect is on: the nominal plant under the same commands departs
    nominal = Plant(f"{ROOT}/host_sim/configs/thesis-900lb.ini")
    base = np.array([nominal.step(cmds[k])[0] for k in range(len(cmds))])
    assert np.max(np.abs(base[:, 2] - p2)) > 100.0     # 5e4 x the tolerance above

"""leveler-plant-server serves the config's [effect.NAME] sections: over real
Modbus TCP (pymodbus, lockstep clock), a vent valve commanded open empties the
pipe at once on the nominal plant and only after its opening delay on a config
with [effect.valve_dynamics]."""
import os

import numpy as np

import rigproc as rp

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))
BASE = os.path.join(ROOT, "host_sim", "configs", "thesis-900lb.ini")


def served_p1_counts(tmp, config):
    """P1 counts: coils all off 100 ms, then the vent valve open 300 ms."""
    plant = rp.Plant(tmp, config=config, clock="lockstep")
    try:
        c = plant.client()
        out = []
        for coils, ms in (([False] * 4, 100), ([False, False, True, False], 300)):
            assert not c.write_coils(0, coils).isError()
            for _ in range(ms // 10):
                assert not c.write_register(0, 10).isError()
                out.append(c.read_input_registers(0, count=4).registers[2])
        c.close()
        return np.array(out)
    finally:
        plant.stop()


def test_a_slow_vent_valve_is_served(tmp_path):
    cfg = tmp_path / "slow-vent.ini"
    cfg.write_text(f"[config]\ninclude = {BASE}\nname = slow-vent\n\n"
                   "[effect.valve_dynamics]\nopen_delay_s = 0.15\n")
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    slow = served_p1_counts(tmp_path / "a", cfg)
    nominal = served_p1_counts(tmp_path / "b", BASE)
    # the vent commanded open at 100 ms: the nominal pipe empties at once, the slow
    # vent holds the pipe's pressure for its 150 ms delay, then empties it too
    assert nominal[19] < nominal[9] - 20
    assert np.all(np.abs(slow[10:23] - slow[9]) <= 1)        # one count of quantisation
    assert slow[-1] < slow[9] - 20

"""The thesis 900 lb case under the emulator against leveler-sim (a real
peer: the same firmware source built for the host), cut short for make test;
make bench runs both thesis cases in full."""

from leveler_pil import case
from leveler_pil.run import Pil

from conftest import CONFIGS


def test_900lb_first_seconds_match_leveler_sim(elf):
    config = CONFIGS / "thesis-900lb.ini"
    pil = Pil(config, elf)
    trace = pil.run_case(end_s=7.0)                     # the load step is at 5 s
    cmp = case.compare(case.trace_log(trace, config), case.sim_log(config, trace.t_s[-1]))
    assert cmp.rows == 701
    assert not pil.resets, f"watchdog resets during the run: {pil.resets}"
    assert cmp.mismatched_ticks == 0, f"actuators differ first at {cmp.first_mismatch_s} s"
    assert {"height_before_step_m", "lowest_height_m", "p2_drop_stop_pa"} <= set(cmp.figures)
    assert cmp.events_agree, cmp.figures
    # The image's own DWT figure (input register tick_cycles_worst) against the
    # harness's count of the same interval (tick + handlers inside it).
    cost = case.tick_summary(pil)
    assert 0 < cost["worst_cycles"] < 720_000
    assert abs(cost["dwt_tick_cycles_worst"] - cost["worst_cycles_with_handlers"]) <= 64

"""leveler.thesis numbers and units, leveler.config keys (the C loader's, through leveler-sim)."""

import pytest

from leveler import config, events, thesis


def test_unit_helpers():
    assert thesis.in_to_m(1.0) == 0.0254
    assert thesis.m_to_in(thesis.in_to_m(15.65)) == pytest.approx(15.65)
    # 14.7 psia is the thesis's atmosphere: 101.35 kPa, within 0.03 % of 101325 Pa.
    assert thesis.psia_to_pa(14.7) == pytest.approx(101325.0, rel=3e-4)
    assert thesis.psig_to_pa(0.0) == pytest.approx(thesis.AMBIENT_PA)
    assert thesis.pa_to_psig(thesis.psia_to_pa(104.7)) == pytest.approx(90.0)
    assert thesis.lb_to_n(1.0) == pytest.approx(4.4482216, rel=1e-8)
    assert thesis.n_to_lb(thesis.lb_to_n(900.0)) == pytest.approx(900.0)


def test_cases_hold_exactly_the_summary_keys_in_si():
    for name, case in thesis.CASES.items():
        assert tuple(case) == events.SUMMARY_KEYS, name
    c = thesis.CASES["thesis-900lb-sim"]
    assert c["lowest_height_m"] == pytest.approx(14.53 * 0.0254)
    assert c["p2_breakaway_pa"] == pytest.approx(105.0 * 6894.757, rel=1e-6)
    assert c["time_stuck_bottom_s"] == 16 and c["time_stuck_top_s"] == 7.5
    assert thesis.CASES["thesis-1000lb-exp"]["p2_drop_stop_pa"] is None
    assert thesis.CASES["thesis-1000lb-acc100psig-exp"]["time_return_after_step_s"] == 2.5


def test_pick_case():
    assert thesis.pick_case("thesis-900lb", "sim") == "thesis-900lb-sim"
    assert thesis.pick_case("thesis-1000lb-tube", "rig") == "thesis-1000lb-exp"
    assert thesis.pick_case("thesis-900lb-exp", "sim") == "thesis-900lb-exp"
    assert thesis.pick_case("bench", "rig", thesis.lb_to_n(1010)) == "thesis-1000lb-exp"
    assert thesis.pick_case("bench", "sim", thesis.lb_to_n(700)) is None


# The text's "Hysteresis Curve Linearization" (slope psi/in, UPlimit and DPlimit
# intercepts psia, y in inches), per load class: the expectation for the
# built-in config, which holds Appendix B's psig lines.
TEXT_LINES_PSIA = {
    900: (-3.43, 144.7, 133.7),
    1000: (-3.67, 154.03, 143.53),
    1100: (-3.5, 156.2, 145.7),
    1200: (-3.67, 164.03, 153.53),
}


def test_program_psig_lines_match_the_texts_psia_lines():
    # Appendix B's lines are psig, the text's psia; with 14.7 psia they agree.
    cfg = config.default_config()
    for lb, (slope, up0, down0) in TEXT_LINES_PSIA.items():
        up, down = cfg.hysteresis_lines(thesis.lb_to_n(lb))
        for y_in in (14.0, 15.65, 17.5):
            h = thesis.in_to_m(y_in)
            assert thesis.pa_to_psia(up(h)) == pytest.approx(slope * y_in + up0, abs=1e-6), lb
            assert thesis.pa_to_psia(down(h)) == pytest.approx(slope * y_in + down0, abs=1e-6), lb


def test_config_keys_units_and_include(tmp_path):
    (tmp_path / "base.ini").write_text(
        "[config]\nname = base\n[controller]\nband_lower_in = 15.6\nband_upper_in = 15.8\n"
        "[hysteresis.1]\nload_below_lbf = 950\nup_slope_psi_per_in = -3.43\n"
        "up_intercept_psig = 130.0\ndown_offset_psi = 11.0\n")
    (tmp_path / "run.ini").write_text(
        "[config]\ninclude = base.ini\nname = thesis-900lb\n; a comment\n"
        "[controller]\nband_lower_mm = 390\n[scenario]\nbase_load_lbf = 900\n"
        "[ambient]\npressure_kpa = 101.325\n")
    cfg = config.load(tmp_path / "run.ini")
    assert cfg.name == "thesis-900lb"
    assert cfg.band_lower_m == pytest.approx(0.390)            # overridden in another unit
    assert cfg.band_upper_m == pytest.approx(15.8 * 0.0254)
    assert cfg.base_load_n == pytest.approx(thesis.lb_to_n(900))
    assert cfg.ambient_pa == pytest.approx(101325.0)
    h = thesis.in_to_m(15.0)
    up, down = cfg.hysteresis_lines(thesis.lb_to_n(900))      # the file's band 1, psig on the file's ambient
    assert up(h) == pytest.approx(thesis.psia_to_pa(-3.43 * 15 + 130.0) + 101325 - thesis.psia_to_pa(0)
                                  , rel=1e-9)
    assert up(h) - down(h) == pytest.approx(11.0 * thesis.PA_PER_PSI)
    up, down = cfg.hysteresis_lines(thesis.lb_to_n(1100))     # the built-in band 3, as the simulator runs it
    assert up(h) == pytest.approx(thesis.psia_to_pa(-3.5 * 15 + 141.5) + 101325 - thesis.psia_to_pa(0),
                                  rel=1e-9)
    assert up(h) - down(h) == pytest.approx(10.5 * thesis.PA_PER_PSI)


@pytest.mark.parametrize("text, words, line", [
    ("[controller]\nband_lower_in = 15.6\nband_lower_mm = 390\n", "given twice", 3),
    ("[controller]\nband_lower_in = abc\n", "band_lower_in = abc: not a number", 2),
    ("[controller]\nband_lower_in = 15.9\nband_upper_in = 15.8\n", "band_lower must be below band_upper", 3),
    ("[hysteresis.1]\nload_below_lbf = 950\nup_slope_psi_per_in = -3.43\n"
     "up_intercept_psig = 130\n", "[hysteresis.1] down_offset: missing", None),
])
def test_config_errors_name_file_line_and_key(tmp_path, text, words, line):
    p = tmp_path / "bad.ini"
    p.write_text(text)
    with pytest.raises(config.ConfigError) as err:
        config.load(p)
    msg = str(err.value)
    assert msg.startswith(f"{p}:{line}:" if line else f"{p}:"), msg
    assert words in msg, msg

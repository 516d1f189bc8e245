"""Published numbers of the thesis, in SI, and unit helpers.

Source: /work/shared/reference/README.md ("Published numbers") which collects
the figures quoted in the text of Chapter III (simulation) and Chapter IV
(experiment). Each case is a dict with exactly the event-summary keys of
``leveler.events.SUMMARY_KEYS``; a figure the thesis does not publish is None.

Pressures are absolute pascals. The thesis quotes psia (and psig for the
accumulator charge); ambient is taken as 14.7 psia, as in the thesis program.
"""

from __future__ import annotations

import math

# --- unit helpers ------------------------------------------------------------

M_PER_IN = 0.0254                     # exact
PA_PER_PSI = 6894.757293168361        # 1 lbf/in^2 = 4.4482216152605 N / (0.0254 m)^2
N_PER_LBF = 4.4482216152605           # exact (international pound-force)
AMBIENT_PSIA = 14.7                   # the thesis's atmosphere
AMBIENT_PA = AMBIENT_PSIA * PA_PER_PSI


def in_to_m(x):
    return x * M_PER_IN


def m_to_in(x):
    return x / M_PER_IN


def psia_to_pa(x):
    """Absolute psi -> absolute Pa."""
    return x * PA_PER_PSI


def pa_to_psia(x):
    """Absolute Pa -> absolute psi."""
    return x / PA_PER_PSI


def psig_to_pa(x):
    """Gauge psi (thesis ambient 14.7 psia) -> absolute Pa."""
    return (x + AMBIENT_PSIA) * PA_PER_PSI


def pa_to_psig(x):
    """Absolute Pa -> gauge psi (thesis ambient 14.7 psia)."""
    return x / PA_PER_PSI - AMBIENT_PSIA


def lb_to_n(x):
    """Pound (weight, lbf) -> newton."""
    return x * N_PER_LBF


def n_to_lb(x):
    return x / N_PER_LBF


# --- the scenario ------------------------------------------------------------

SCENARIO = {
    "step_time_s": 5.0,
    "removal_time_s": 35.0,
    "end_time_s": 55.0,
    "step_load_n": lb_to_n(200.0),
    "set_height_m": in_to_m(15.65),
}

# Which unit each summary key is shown in beside the thesis.
# kind: "length" (m <-> in), "pressure" (Pa abs <-> psia), "time" (s).
KEY_KIND = {
    "height_before_step_m": "length",
    "lowest_height_m": "length",
    "p2_drop_stop_pa": "pressure",
    "time_stuck_bottom_s": "time",
    "p2_breakaway_pa": "pressure",
    "time_return_after_step_s": "time",
    "p2_after_climb_pa": "pressure",
    "highest_height_m": "length",
    "p2_jump_pa": "pressure",
    "time_stuck_top_s": "time",
    "p2_start_down_pa": "pressure",
    "time_return_after_removal_s": "time",
}


def to_thesis_units(key, value):
    """SI value of a summary key -> (value in thesis units, unit name)."""
    kind = KEY_KIND[key]
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return None, _THESIS_UNIT[kind]
    if kind == "length":
        return m_to_in(value), "in"
    if kind == "pressure":
        return pa_to_psia(value), "psia"
    return value, "s"


def si_unit(key):
    return {"length": "m", "pressure": "Pa", "time": "s"}[KEY_KIND[key]]


_THESIS_UNIT = {"length": "in", "pressure": "psia", "time": "s"}


def _case(height_before=None, lowest=None, p2_drop_stop=None, stuck_bottom=None,
          p2_breakaway=None, return_after_step=None, p2_after_climb=None,
          highest=None, p2_jump=None, stuck_top=None, p2_start_down=None,
          return_after_removal=None):
    """Builds a case from thesis units (in, psia, s) into the SI summary keys."""
    def opt(f, v):
        return None if v is None else f(v)
    return {
        "height_before_step_m": opt(in_to_m, height_before),
        "lowest_height_m": opt(in_to_m, lowest),
        "p2_drop_stop_pa": opt(psia_to_pa, p2_drop_stop),
        "time_stuck_bottom_s": stuck_bottom,
        "p2_breakaway_pa": opt(psia_to_pa, p2_breakaway),
        "time_return_after_step_s": return_after_step,
        "p2_after_climb_pa": opt(psia_to_pa, p2_after_climb),
        "highest_height_m": opt(in_to_m, highest),
        "p2_jump_pa": opt(psia_to_pa, p2_jump),
        "time_stuck_top_s": stuck_top,
        "p2_start_down_pa": opt(psia_to_pa, p2_start_down),
        "time_return_after_removal_s": return_after_removal,
    }


# --- published cases ---------------------------------------------------------
# Times "to return into the band" are not published for the plain cases (the
# text gives the stuck times and, for 1000 lb sim, "about 10 s" of climb only).

CASES = {
    "thesis-900lb-sim": _case(15.65, 14.53, 96, 16, 105, None, 101, 17.54, 84, 7.5, 74),
    "thesis-900lb-exp": _case(15.65, 14.6, 94, 19, 105, None, 100.5, 17.5, 84, 8, 75),
    "thesis-1000lb-sim": _case(15.65, 14.41, 101, 13, 111, None, 107, 17.43, 90, 7, 78),
    # "~17 s" and "~10 s" in the text.
    "thesis-1000lb-exp": _case(15.65, 14.5, None, 17, 111, None, None, 17.5, None, 10, None),
    # Accumulator experiments (diaphragm accumulator; load step only).
    # 90 psig: drop to 14.9 in; return "3 s sooner" than without (relative only).
    "thesis-900lb-acc90psig-exp": _case(15.65, 14.9),
    # 100 psig: "the displacement change was not improved"; return in about 2.5 s.
    "thesis-900lb-acc100psig-exp": _case(15.65, None, return_after_step=2.5),
    "thesis-900lb-acc112psig-exp": _case(15.65, None, return_after_step=2.0),
    "thesis-1000lb-acc100psig-exp": _case(15.65, 14.82, return_after_step=2.5),
    # 110 psig: "about 0.1 second" faster than 100 psig.
    "thesis-1000lb-acc110psig-exp": _case(15.65, None, return_after_step=2.4),
    # 120 psig: "no time delay" (no figure).
    "thesis-1000lb-acc120psig-exp": _case(15.65, None),
}

# Figures quoted in the text that are not event-summary keys.
EXTRA = {
    "thesis-900lb-sim": {"p2_before_step_pa": psia_to_pa(89.0)},
    "thesis-900lb-exp": {"p2_before_step_pa": psia_to_pa(89.0),
                         # the accumulator section quotes 14.55 in as the no-accumulator drop
                         "lowest_height_acc_section_m": in_to_m(14.55)},
    "thesis-1000lb-exp": {"lowest_height_acc_section_m": in_to_m(14.48)},
}

ACCUMULATOR_CHARGE_PA = {
    "thesis-900lb-acc90psig-exp": psig_to_pa(90.0),
    "thesis-900lb-acc100psig-exp": psig_to_pa(100.0),
    "thesis-900lb-acc112psig-exp": psig_to_pa(112.0),
    "thesis-1000lb-acc100psig-exp": psig_to_pa(100.0),
    "thesis-1000lb-acc110psig-exp": psig_to_pa(110.0),
    "thesis-1000lb-acc120psig-exp": psig_to_pa(120.0),
}


def pick_case(config_name=None, source=None, base_load_n=None, accumulator=None):
    """Chooses the published case to set a run beside.

    ``accumulator`` (type, charge in Pa absolute), when given, must fit the
    case too: a run without one is set beside the no-accumulator case, a
    diaphragm run beside the accumulator experiment of its base load and
    charge (within 0.5 psi), and anything else (a tube, another charge) beside
    nothing: the thesis published no figures for it.

    An exact case name as config name wins. Otherwise the base load is the
    one named in the config name ("...900lb...") or, failing that, the
    nearest of 900 / 1000 lb to ``base_load_n`` (within 50 lb); ``source``
    "rig" selects the experiment, anything else the simulation. Returns a
    case name or None when nothing fits.
    """
    if config_name in CASES:
        return config_name
    base_lb = None
    if config_name:
        for lb in (1000, 900):
            if f"{lb}lb" in config_name.replace(" ", "").lower():
                base_lb = lb
                break
    if base_lb is None and base_load_n is not None and math.isfinite(base_load_n):
        lb = n_to_lb(base_load_n)
        nearest = min((900, 1000), key=lambda c: abs(c - lb))
        if abs(nearest - lb) <= 50.0:
            base_lb = nearest
    if base_lb is None:
        return None
    if accumulator is not None and accumulator[0] != "none":
        if accumulator[0] != "diaphragm":
            return None
        for case, charge in ACCUMULATOR_CHARGE_PA.items():
            if case.startswith(f"thesis-{base_lb}lb-") and abs(charge - accumulator[1]) <= 0.5 * PA_PER_PSI:
                return case
        return None
    kind = "exp" if source == "rig" else "sim"
    return f"thesis-{base_lb}lb-{kind}"

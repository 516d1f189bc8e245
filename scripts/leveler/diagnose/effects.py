"""The catalogue of candidate unmodelled effects.

Each candidate is an optional extension of the C plant (host_sim/plant/effects.c)
with a few parameters in physically bounded ranges. All parameters at their
`nominal` value reproduce the nominal plant exactly. The order of `params` is
the order of the doubles passed to the C plant (effects.h).
"""
from dataclasses import dataclass


@dataclass(frozen=True)
class Param:
    name: str
    lo: float
    hi: float
    nominal: float
    log: bool = False   # fit in log space (time constants, areas spanning decades)
    doc: str = ""


@dataclass(frozen=True)
class Effect:
    name: str
    effect_id: int      # effects.h: plant_effect_kind
    params: tuple
    doc: str

    @property
    def names(self):
        return [p.name for p in self.params]

    def nominal(self):
        return {p.name: p.nominal for p in self.params}


# Physical ranges: the rig is a 2 mm solenoid valve, 12.5 in^3 pipe,
# 210-270 in^3 rolling-lobe spring, 900-1200 lb platform.
EFFECTS = (
    Effect("thermal", 1, (
        Param("tau_thermal_s", 0.3, 60.0, 0.0, log=True,
              doc="gas-to-wall heat exchange time constant; the exponent moves from k (fast) "
                  "toward 1 (slow) instead of a fixed n"),
    ), "gas heat exchange with the walls (spring, pipe, accumulator)"),
    Effect("area", 2, (
        Param("area_slope_rel_per_m", -6.0, 6.0, 0.0,
              doc="extra relative change of effective area per metre of height"),
        Param("area_curv_rel_per_m2", -200.0, 200.0, 0.0,
              doc="relative curvature of effective area against height"),
        Param("area_offset_rel", -0.1, 0.1, 0.0,
              doc="relative effective-area error at the reference height"),
    ), "nonlinear effective area and volume against height"),
    Effect("friction", 3, (
        Param("coulomb_n", 0.0, 400.0, 0.0, doc="Coulomb friction of the platform guide"),
        Param("stribeck_n", 0.0, 400.0, 0.0, doc="extra static (Stribeck) friction at rest"),
        Param("stribeck_v_m_s", 5e-4, 0.05, 0.005, log=True, doc="Stribeck velocity"),
    ), "Coulomb and Stribeck friction of the platform guide"),
    Effect("valve_dynamics", 4, (
        Param("open_delay_s", 0.0, 0.4, 0.0, doc="solenoid and vent opening delay"),
        Param("close_delay_s", 0.0, 0.4, 0.0, doc="closing delay"),
        Param("b_critical", 0.05, 0.6, 0.0, doc="ISO 6358 critical pressure ratio b (0 = nominal eq. 8)"),
        Param("c_out_scale", 0.3, 2.0, 1.0, doc="sonic conductance of outflow relative to nominal"),
    ), "valve opening/closing delays and ISO 6358 flow"),
    Effect("line_delay", 5, (
        Param("delay_s", 0.0, 0.5, 0.0, doc="transport delay of the tube compressor -> spring"),
        Param("dead_volume_m3", 0.0, 1.0e-3, 0.0,
              doc="the tube's volume, added to the junction (0..61 in^3)"),
    ), "transport delay and dead volume of the compressor-spring tube"),
    Effect("leak", 6, (
        Param("leak_area_m2", 1e-10, 3e-7, 0.0, log=True, doc="equivalent orifice area spring -> ambient"),
    ), "leak from the spring to ambient"),
    Effect("sensor_lag", 7, (
        Param("tau_pressure_s", 0.0, 1.0, 0.0, doc="first-order lag of the pressure transducers"),
        Param("tau_height_s", 0.0, 1.0, 0.0, doc="first-order lag of the LVDT"),
        Param("p_offset_pa", -8000.0, 8000.0, 0.0, doc="offset of the spring pressure transducer"),
        Param("h_offset_m", -0.003, 0.003, 0.0, doc="offset of the LVDT"),
    ), "first-order lag and offset of the pressure and height transducers"),
)

BY_NAME = {e.name: e for e in EFFECTS}
NAMES = [e.name for e in EFFECTS]


def get(name):
    try:
        return BY_NAME[name]
    except KeyError:
        raise KeyError(f"unknown effect {name!r}; known: {', '.join(NAMES)}") from None

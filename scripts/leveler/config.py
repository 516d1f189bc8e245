"""The few simulator-config keys the analysis needs (docs/config-format.md).

Reads an INI file with ``configparser`` (following ``[config] include``) and
returns, in SI: the run name, the controller band, the ambient pressure, the
base load and the hysteresis bands. Every other key is the simulator's
business and is ignored here. Errors name the file, the line and the
``[section] key``.
"""

from __future__ import annotations

import configparser
import dataclasses
import os
import re
from typing import Dict, List, Optional, Tuple

from . import thesis

# unit suffix -> (scale, offset) with SI = value * scale + offset
_PSI = thesis.PA_PER_PSI
LENGTH = {"m": (1.0, 0.0), "mm": (1e-3, 0.0), "in": (thesis.M_PER_IN, 0.0)}
FORCE = {"n": (1.0, 0.0), "lbf": (thesis.N_PER_LBF, 0.0)}
PRESSURE_ABS = {"pa": (1.0, 0.0), "kpa": (1e3, 0.0), "bar": (1e5, 0.0), "psia": (_PSI, 0.0)}
PRESSURE_GAUGE = {"pag": (1.0, None), "psig": (_PSI, None)}     # None: + ambient
PRESSURE_DIFF = {"pad": (1.0, 0.0), "psi": (_PSI, 0.0)}
HYST_SLOPE = {"pa_per_m": (1.0, 0.0), "psi_per_in": (_PSI / thesis.M_PER_IN, 0.0)}


class ConfigError(ValueError):
    """``str()`` reads ``file:line: [section] key: what is wrong``."""


@dataclasses.dataclass
class HysteresisBand:
    load_below_n: float
    up_slope_pa_per_m: float
    up_intercept_gauge_pa: float
    down_offset_pa: float

    def up_pa(self, height_m, ambient_pa):
        """UPlimit as absolute pressure at ``height_m``."""
        return self.up_slope_pa_per_m * height_m + self.up_intercept_gauge_pa + ambient_pa

    def down_pa(self, height_m, ambient_pa):
        return self.up_pa(height_m, ambient_pa) - self.down_offset_pa


@dataclasses.dataclass
class AnalysisConfig:
    name: str
    band_low_m: float
    band_high_m: float
    ambient_pa: float
    base_load_n: Optional[float]
    hysteresis: List[HysteresisBand]
    path: Optional[str] = None

    def band_for_load(self, load_n) -> HysteresisBand:
        """The band the program uses: the first (by load_below) whose
        load_below exceeds the load, else the heaviest band."""
        bands = sorted(self.hysteresis, key=lambda b: b.load_below_n)
        for b in bands:
            if load_n < b.load_below_n:
                return b
        return bands[-1]

    def hysteresis_lines(self, load_n):
        """(up, down): height_m -> absolute Pa for the current load."""
        b = self.band_for_load(load_n)
        return (lambda h: b.up_pa(h, self.ambient_pa), lambda h: b.down_pa(h, self.ambient_pa))


def thesis_hysteresis() -> List[HysteresisBand]:
    """The thesis program's four bands (psig lines, README)."""
    rows = [(950, -3.43, 130.0, 11.0), (1050, -3.67, 139.33, 10.5),
            (1150, -3.5, 141.5, 10.5), (1e9, -3.67, 149.33, 10.5)]
    # The last band covers every heavier load; its limit is the largest.
    return [HysteresisBand(thesis.lb_to_n(lb) if lb < 1e8 else 1e5,
                           s * _PSI / thesis.M_PER_IN, c * _PSI, off * _PSI)
            for lb, s, c, off in rows]


def default_config(name="") -> AnalysisConfig:
    """Thesis band, ambient 14.7 psia and hysteresis lines, no config file."""
    return AnalysisConfig(name, thesis.SCENARIO["band_low_m"], thesis.SCENARIO["band_high_m"],
                          thesis.AMBIENT_PA, None, thesis_hysteresis())


# --- reading -------------------------------------------------------------------

def _line_of(path, section, key):
    """Line number of ``key`` in ``[section]`` of ``path`` (1-based) or None."""
    try:
        with open(path, encoding="utf-8") as f:
            current = None
            for n, line in enumerate(f, 1):
                s = line.strip()
                m = re.match(r"^\[(.+)\]$", s)
                if m:
                    current = m.group(1).strip().lower()
                elif current == section.lower() and re.match(
                        rf"^{re.escape(key)}\s*[=:]", s, re.IGNORECASE):
                    return n
    except OSError:
        return None
    return None


def _error(path, section, key, message):
    line = _line_of(path, section, key) if key else None
    where = f"{path}:{line}" if line else str(path)
    what = f"[{section}] {key}" if key else f"[{section}]"
    return ConfigError(f"{where}: {what}: {message}")


def _load_chain(path, depth=0) -> List[Tuple[str, configparser.ConfigParser]]:
    """The file and its includes, the including file last (it wins)."""
    if depth > 4:
        raise ConfigError(f"{path}: includes nested more than 4 deep")
    cp = configparser.ConfigParser(interpolation=None, strict=True,
                                   comment_prefixes=("#", ";"), inline_comment_prefixes=None)
    try:
        with open(path, encoding="utf-8") as f:
            cp.read_file(f, source=path)
    except OSError as e:
        raise ConfigError(f"{path}: cannot read: {e.strerror}") from None
    except configparser.Error as e:
        raise ConfigError(f"{path}: {e}".replace("\n", " ")) from None
    chain = []
    if cp.has_option("config", "include"):
        inc = cp.get("config", "include").strip()
        inc_path = os.path.join(os.path.dirname(os.path.abspath(path)), inc)
        chain.extend(_load_chain(inc_path, depth + 1))
    chain.append((path, cp))
    return chain


def _lookup(chain, section, base, units):
    """The last value of ``base_<unit>`` for any unit in ``units``, in SI, and
    (file, key) it came from; (None, None) if absent. ``units`` values are
    (scale, offset); offset None marks a gauge pressure, kept gauge here."""
    found = None
    for path, cp in chain:
        if not cp.has_section(section):
            continue
        hits = [(u, cp.get(section, f"{base}_{u}")) for u in units
                if cp.has_option(section, f"{base}_{u}")]
        if len(hits) > 1:
            keys = sorted((f"{base}_{u}" for u, _ in hits),
                          key=lambda k: _line_of(path, section, k) or 0)
            raise _error(path, section, keys[-1], f"given twice (also as {keys[0]})")
        if hits:
            u, text = hits[0]
            try:
                value = float(text)
            except ValueError:
                raise _error(path, section, f"{base}_{u}", f"'{text}' is not a number") from None
            found = (u, value, path)
    if found is None:
        return None, None
    u, value, path = found
    scale, offset = units[u]
    return value * scale + (offset or 0.0), (path, f"{base}_{u}")


def raw_value(path, section, key) -> Optional[str]:
    """The text of ``[section] key`` as the simulator sees it: the last one
    along the file's include chain; None when no file gives it."""
    value = None
    for _, cp in _load_chain(os.fspath(path)):
        if cp.has_option(section, key):
            value = cp.get(section, key).strip()
    return value


def load(path) -> AnalysisConfig:
    """Reads the keys the analysis needs from a simulator config file."""
    path = os.fspath(path)
    chain = _load_chain(path)
    name = None
    for _, cp in chain:
        if cp.has_option("config", "name"):
            name = cp.get("config", "name").strip()
    if not name:
        name = os.path.splitext(os.path.basename(path))[0]

    ambient, _ = _lookup(chain, "ambient", "pressure", PRESSURE_ABS)
    ambient = thesis.AMBIENT_PA if ambient is None else ambient

    lo, _ = _lookup(chain, "controller", "band_lower", LENGTH)
    hi, where = _lookup(chain, "controller", "band_upper", LENGTH)
    lo = thesis.SCENARIO["band_low_m"] if lo is None else lo
    hi = thesis.SCENARIO["band_high_m"] if hi is None else hi
    if not hi > lo:
        file_, key = where if where else (path, "band_upper")
        raise _error(file_, "controller", key, f"upper {hi:.6g} m is not above lower {lo:.6g} m")

    base, _ = _lookup(chain, "scenario", "base_load", FORCE)

    bands: Dict[int, HysteresisBand] = {}
    sections = sorted({s for _, cp in chain for s in cp.sections() if s.startswith("hysteresis.")})
    for sec in sections:
        m = re.fullmatch(r"hysteresis\.([1-8])", sec)
        if not m:
            raise _error(path, sec, None, "hysteresis sections are [hysteresis.1] .. [hysteresis.8]")
        values = {}
        for base_key, units in (("load_below", FORCE), ("up_slope", HYST_SLOPE),
                                ("up_intercept", {**PRESSURE_GAUGE, **PRESSURE_DIFF}),
                                ("down_offset", PRESSURE_DIFF)):
            v, _ = _lookup(chain, sec, base_key, units)
            if v is None:
                raise _error(path, sec, base_key, "missing (with a unit suffix, e.g. "
                             f"{base_key}_{next(iter(units))})")
            values[base_key] = v
        bands[int(m.group(1))] = HysteresisBand(values["load_below"], values["up_slope"],
                                                values["up_intercept"], values["down_offset"])
    hyst = [bands[k] for k in sorted(bands)] if bands else thesis_hysteresis()
    return AnalysisConfig(name, lo, hi, ambient, base, hyst, path)

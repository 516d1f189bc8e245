"""The simulator's config as the C loader resolves it (docs/config-format.md).

There is one config loader, the simulator's (host_sim/plant/plant_config_*.c:
units, ranges, includes, the built-in thesis-900lb.ini, [effect.NAME] sections). Python asks it
through the engine's one binding (leveler.engine: Engine(path).config_json(), the same
JSON ``leveler-sim --dump-config`` prints): every key in SI with its SI unit
suffix, the hysteresis bands with the load range each covers, the effects.
Errors are the loader's own ``file:line: [section] key = value: reason``.

``find_sim`` finds ``leveler-sim`` for those who run it: $LEVELER_SIM, else the
installed package (pip install .), else the project's build folders
(leveler/paths.py).
"""

from __future__ import annotations

import dataclasses
import functools
import os
from typing import List, Optional

from . import engine, paths
from .errors import InputError


class ConfigError(InputError, ValueError):
    """``str()`` reads ``file:line: [section] key ...: what is wrong`` (the C loader's words)."""


@dataclasses.dataclass
class HysteresisBand:
    load_below_n: float
    up_slope_pa_per_m: float
    up_intercept_gauge_pa: float
    down_offset_pa: float
    covers_from_n: float                 # the loads this band is used for, as the plant picks it
    covers_below_n: Optional[float]      # None: every heavier load

    def covers(self, load_n):
        return self.covers_from_n <= load_n and (self.covers_below_n is None or load_n < self.covers_below_n)

    def up_pa(self, height_m, ambient_pa):
        """UPlimit as absolute pressure at ``height_m``."""
        return self.up_slope_pa_per_m * height_m + self.up_intercept_gauge_pa + ambient_pa

    def down_pa(self, height_m, ambient_pa):
        return self.up_pa(height_m, ambient_pa) - self.down_offset_pa


@dataclasses.dataclass
class AnalysisConfig:
    name: str
    band_lower_m: float
    band_upper_m: float
    ambient_pa: float
    base_load_n: float
    hysteresis: List[HysteresisBand]
    path: Optional[str] = None
    values: dict = dataclasses.field(default_factory=dict)   # the whole resolved config (JSON)

    def band_for_load(self, load_n) -> HysteresisBand:
        """The band the plant uses for this load (the load ranges come from the C plant)."""
        for b in self.hysteresis:
            if b.covers(load_n):
                return b
        raise ValueError(f"no hysteresis band covers {load_n} N")

    def hysteresis_lines(self, load_n):
        """(up, down): height_m -> absolute Pa for the current load."""
        b = self.band_for_load(load_n)
        return (lambda h: b.up_pa(h, self.ambient_pa), lambda h: b.down_pa(h, self.ambient_pa))

    def value(self, section, key):
        """A resolved value by section and SI key, e.g. ("solver", "substeps_per_tick")."""
        return self.values[section][key]


def _executable(path):
    return os.path.isfile(path) and os.access(path, os.X_OK)


def find_sim():
    try:
        return paths.compiled("LEVELER_SIM", "_bin/leveler-sim", "host_sim/sim/leveler-sim",
                              "it reads the config for the analysis: run `make sim`", ok=_executable)
    except paths.NotFound as e:
        raise ConfigError(str(e)) from None


@functools.lru_cache(maxsize=64)
def _resolved(path, mtime):
    try:
        return engine.config_json(path)
    except (engine.EngineError, InputError) as e:
        raise ConfigError(str(e)) from None


def resolved(path=None) -> dict:
    """The resolved config as the C loader gives it (the built-in one for None)."""
    if path is None:
        return _resolved(None, None)
    path = os.fspath(path)
    try:
        mtime = os.stat(path).st_mtime_ns
    except OSError as e:
        raise ConfigError(f"{path}: cannot open: {e.strerror}") from None
    return _resolved(path, mtime)


def _analysis(doc, path) -> AnalysisConfig:
    bands = [HysteresisBand(b["load_below_n"], b["up_slope_pa_per_m"], b["up_intercept_pag"],
                            b["down_offset_pad"], b["covers_from_n"], b["covers_below_n"])
             for b in doc["hysteresis"]]
    return AnalysisConfig(doc["config"]["name"], doc["controller"]["band_lower_m"],
                          doc["controller"]["band_upper_m"], doc["ambient"]["pressure_pa"],
                          doc["scenario"]["base_load_n"], bands, path, doc)


def load(path) -> AnalysisConfig:
    """A simulator config file, resolved by the C loader."""
    return _analysis(resolved(path), os.fspath(path))


def default_config(name="") -> AnalysisConfig:
    """The built-in config (the thesis 900 lb case) when there is no file."""
    cfg = _analysis(resolved(None), None)
    if name:
        cfg = dataclasses.replace(cfg, name=name)
    return cfg

"""The study file: what a sweep varies and measures (docs/sweep.md).

    [study]
    name = "accumulator"
    configs = ["../configs/thesis-900lb-tube.ini"]   # base configs, relative to this file
    algorithms = [2, 3]                                # leveler-sim --algorithm (default: the config's)
    scenarios = ["config"]                             # "config": its [scenario]; else schedule CSVs
    figures = ["time_return_after_step_s", "overshoot_m"]   # default: all (leveler.sweep.figures)
    end_s = 55                                         # optional: leveler-sim --end-s

    [vary]                                             # "section.key" as in the INI, unit and all
    "accumulator.charge_psig" = { from = 90, to = 130, step = 10 }
    "accumulator.volume_in3" = [25, 50, 100]

    [plot]                                             # optional: the heat map's axes, the figures
    x = "accumulator.charge_psig"
    y = "accumulator.volume_in3"
    figures = ["time_return_after_step_s", "overshoot_m", "compressor_on_s", "switchings"]

A point is one combination of base config, scenario, algorithm and one value
of every varied key; its config is an INI that includes the base and sets the
keys (``Point.ini_text``). The C loader validates it (units, ranges), as for
any config: there is no second INI parser here.
"""
from __future__ import annotations

import dataclasses
import hashlib
import itertools
import json
import os
import re
import tomllib
from typing import List, Optional, Tuple

from .. import config as config_mod
from .. import paths
from . import figures

STUDY_DIR = paths.data("host_sim/studies", "studies")     # the shipped studies (--study NAME)

_KEY = re.compile(r"^[a-z][a-z0-9_]*(\.[0-9]+)?\.[a-z][a-z0-9_]*$")
PLOTTED = ("time_return_after_step_s", "overshoot_m", "compressor_on_s", "switchings")   # by default
_STUDY_KEYS = {"name", "title", "configs", "algorithms", "scenarios", "figures", "end_s"}


class StudyError(ValueError):
    """A study file that cannot be used; the message names the file and the key."""


@dataclasses.dataclass(frozen=True)
class Point:
    index: int                 # place in the study's order (the table's order)
    point_id: str              # hash of what defines the point (resume key, Dask key)
    config: str                # the base config's name
    base_path: str             # absolute path of the base INI
    scenario: str              # "config" or the schedule file's name
    schedule: Optional[str]    # absolute path of the schedule, None for "config"
    algorithm: Optional[int]   # None: the config's own
    settings: Tuple[Tuple[str, object], ...]   # (section.key, value) in the study's order
    end_s: Optional[float]

    def ini_text(self):
        """The point's config: the base included, then the changed keys by section."""
        lines = [f"; leveler-sweep point {self.point_id}", "[config]", f"include = {self.base_path}"]
        by_section = {}
        for key, value in self.settings:
            section, name = key.rsplit(".", 1)
            by_section.setdefault(section, []).append(f"{name} = {format_value(value)}")
        for section, keys in by_section.items():
            lines += ["", f"[{section}]"] + keys
        return "\n".join(lines) + "\n"


@dataclasses.dataclass
class Study:
    path: str
    name: str
    configs: List[Tuple[str, str, str]]        # (name, absolute path, resolved hash)
    scenarios: List[Tuple[str, Optional[str], str]]   # (name, absolute path or None, content hash)
    algorithms: List[Optional[int]]
    vary: List[Tuple[str, list]]               # (section.key, values) in file order
    figures: List[str]
    end_s: Optional[float]
    plot_axes: List[str]
    plot_figures: List[str]

    @property
    def keys(self):
        return [k for k, _ in self.vary]

    def points(self) -> List[Point]:
        dims = [self.configs, self.scenarios, self.algorithms] + [values for _, values in self.vary]
        out = []
        for i, combo in enumerate(itertools.product(*dims)):
            (cname, cpath, chash), (sname, spath, shash), alg = combo[:3]
            settings = tuple(zip(self.keys, combo[3:]))
            ident = json.dumps({"base": chash, "scenario": shash, "algorithm": alg, "end_s": self.end_s,
                                "set": [[k, v] for k, v in settings]}, sort_keys=True)
            pid = hashlib.sha256(ident.encode()).hexdigest()[:16]
            out.append(Point(i, pid, cname, cpath, sname, spath, alg, settings, self.end_s))
        return out


def format_value(value):
    """A value as the INI line gets it (shortest exact decimal for a float)."""
    if isinstance(value, float):
        return repr(int(value)) if value.is_integer() and abs(value) < 1e15 else repr(value)
    return str(value)


def resolved_hash(doc):
    """sha256 of a resolved config (leveler-sim --dump-config) without its file path."""
    doc = dict(doc, config={k: v for k, v in doc["config"].items() if k != "path"})
    return hashlib.sha256(json.dumps(doc, sort_keys=True, separators=(",", ":")).encode()).hexdigest()


def expand_range(spec, where):
    """{from, to, step} (to included when on the grid) or {from, to, count}: the values."""
    if set(spec) not in ({"from", "to", "step"}, {"from", "to", "count"}):
        raise StudyError(f"{where}: a range is {{from, to, step}} or {{from, to, count}} (got {sorted(spec)})")
    lo, hi = spec["from"], spec["to"]
    if "step" in spec:
        step = spec["step"]
        if not step or (hi - lo) / step < 0:
            raise StudyError(f"{where}: step {step} does not go from {lo} to {hi}")
        n = int((hi - lo) / step + 1e-9) + 1
        values = [lo + i * step for i in range(n)]
    else:
        n = spec["count"]
        if not isinstance(n, int) or n < 2:
            raise StudyError(f"{where}: count must be an integer >= 2")
        values = [lo + (hi - lo) * i / (n - 1) for i in range(n)]
    values = [round(v, 10) for v in values]
    return [int(v) for v in values] if all(float(v).is_integer() for v in values) else values


def _values(key, spec, where):
    if not _KEY.match(key):
        raise StudyError(f"{where}: '{key}' is not section.key (e.g. accumulator.charge_psig)")
    values = expand_range(spec, where) if isinstance(spec, dict) else spec
    if not isinstance(values, list) or not values:
        raise StudyError(f"{where}: give a list of values or a range")
    for v in values:
        if isinstance(v, bool) or not isinstance(v, (int, float, str)) or (isinstance(v, str) and
                                                                          not re.match(r"^[\w.+-]+$", v)):
            raise StudyError(f"{where}: {v!r} is not a number or a plain word")
    if len(set(values)) != len(values):
        raise StudyError(f"{where}: a value is given twice")
    return values


def _file_hash(path, where):
    try:
        with open(path, "rb") as fh:
            return hashlib.sha256(fh.read()).hexdigest()
    except OSError as e:
        raise StudyError(f"{where}: {path}: {e.strerror}") from None


def _configs(paths, here, where):
    out = []
    for p in paths:
        path = os.path.abspath(os.path.join(here, p))
        try:
            doc = config_mod.resolved(path)
        except config_mod.ConfigError as e:
            raise StudyError(f"{where}: {e}") from None
        out.append((doc["config"]["name"], path, resolved_hash(doc)))
    if len({name for name, _, _ in out}) != len(out):
        raise StudyError(f"{where}: two base configs have the same [config] name")
    return out


def _scenarios(names, here, where):
    out = []
    for s in names:
        if s == "config":
            out.append(("config", None, "config"))
        else:
            path = os.path.abspath(os.path.join(here, s))
            out.append((os.path.basename(s), path, _file_hash(path, where)))
    return out


def _list(table, key, where, default):
    v = table.get(key, default)
    if not isinstance(v, list) or not v:
        raise StudyError(f"{where}: [study] {key}: give a non-empty list")
    return v


def find(name_or_path):
    """A study file: the path given, else a shipped study's name (host_sim/studies/NAME.toml)."""
    if os.path.exists(name_or_path) or os.sep in name_or_path or name_or_path.endswith(".toml"):
        return name_or_path
    path = os.path.join(STUDY_DIR, name_or_path + ".toml")
    if not os.path.exists(path):
        known = sorted(n[:-5] for n in os.listdir(STUDY_DIR) if n.endswith(".toml")) if os.path.isdir(STUDY_DIR) else []
        raise StudyError(f"--study {name_or_path}: no such file, nor a shipped study (known: {', '.join(known)})")
    return path


def load(path) -> Study:
    """Reads and checks a study file; the base configs are resolved by the C loader."""
    try:
        with open(path, "rb") as fh:
            doc = tomllib.load(fh)
    except OSError as e:
        raise StudyError(f"{path}: {e.strerror}") from None
    except tomllib.TOMLDecodeError as e:
        raise StudyError(f"{path}: {e}") from None
    for table in sorted(set(doc) - {"study", "vary", "plot"}):
        raise StudyError(f"{path}: unknown table [{table}] (study, vary, plot)")
    for key in sorted(set(doc.get("study", {})) - _STUDY_KEYS):
        raise StudyError(f"{path}: [study] {key}: unknown key ({', '.join(sorted(_STUDY_KEYS))})")
    s, here = doc.get("study", {}), os.path.dirname(os.path.abspath(path))
    algorithms = s.get("algorithms", [None])
    if any(a not in (1, 2, 3, None) for a in algorithms):
        raise StudyError(f"{path}: [study] algorithms: each 1, 2 or 3")
    names = _list(s, "figures", path, list(figures.NAMES))
    bad = [f for f in names if f not in figures.NAMES]
    if bad:
        raise StudyError(f"{path}: [study] figures: {bad[0]!r} is not one of {', '.join(figures.NAMES)}")
    vary = [(k, _values(k, v, f"{path}: [vary] {k}")) for k, v in doc.get("vary", {}).items()]
    plot = doc.get("plot", {})
    axes = [plot[a] for a in ("x", "y") if plot.get(a)]
    if any(a not in dict(vary) for a in axes):
        raise StudyError(f"{path}: [plot] names a key that is not in [vary]")
    plotted = plot.get("figures", [f for f in PLOTTED if f in names])
    if any(f not in names or f not in figures.LABELS for f in plotted):
        raise StudyError(f"{path}: [plot] figures: each one of [study] figures and of {', '.join(figures.LABELS)}")
    end = s.get("end_s")
    return Study(os.path.abspath(path), str(s.get("name", os.path.splitext(os.path.basename(path))[0])),
                 _configs(_list(s, "configs", path, None), here, f"{path}: [study] configs"),
                 _scenarios(_list(s, "scenarios", path, ["config"]), here, f"{path}: [study] scenarios"),
                 algorithms, vary, names, None if end is None else float(end), axes, plotted)

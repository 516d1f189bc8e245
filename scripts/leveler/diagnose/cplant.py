"""The project's C plant through ctypes (host_sim/diagnose/diag_shim.c, host_sim/plant/effects*.c).

The shared library `libleveler_diag.so` is built without sanitizers by
host_sim/diagnose/CMakeLists.txt. It is looked up in $LEVELER_DIAG_LIB, then in
the project's build folders (build/sim, build/bench, build/test).
"""
import ctypes
import functools
import glob
import os

import numpy as np

from . import effects as fx
from .errors import DiagnoseInputError
from .model import CLOSED_LOOP, Simulator, Trace

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..", ".."))
CONFIG_DIR = os.path.join(ROOT, "host_sim", "configs")
ABI = 1
MAX_PARAMS = 8
SIGNALS = ("height_m", "p_spring_pa", "p_pipe_pa", "p_acc_pa")
COMMANDS = ("compressor", "spring_valve", "vent_valve", "acc_valve")
SCENARIO_KEYS = ("base_load_n", "step_load_n", "step_on_s", "step_off_s", "end_s")


def find_library(env="LEVELER_DIAG_LIB", folder="diagnose", name="libleveler_diag.so", target="leveler_diag"):
    path = os.environ.get(env)
    if path:
        if not os.path.isfile(path):
            raise DiagnoseInputError(f"{env}={path}: no such file")
        return path
    cands = []
    for b in ("build/sim", "build/bench", "build/test", "build/*"):
        cands += glob.glob(os.path.join(ROOT, b, "host_sim", folder, name))
    cands = [c for c in cands if os.path.isfile(c)]
    if not cands:
        raise DiagnoseInputError(f"{name} not found: build it with "
                                 f"`cmake --build build/sim --target {target}` or set {env}")
    return max(cands, key=os.path.getmtime)


def find_truth_library():
    """The blind test's truth variants (host_sim/blindtest/), not part of the product."""
    return find_library("LEVELER_TRUTH_LIB", "blindtest", "libleveler_truth.so", "leveler_truth")


@functools.lru_cache(maxsize=None)
def _library(path):
    return ctypes.CDLL(path)


def scenario_loads(t_s, scenario):
    """The load over each tick from t_s[i] of a scenario (dict of the config's [scenario]
    keys base_load_n, step_load_n, step_on_s, step_off_s, end_s), by the simulator's rule."""
    f = _library(find_library()).diag_scenario_loads
    f.restype = None
    f.argtypes = [ctypes.c_double] * 5 + [ctypes.c_int, ctypes.POINTER(ctypes.c_double),
                                          ctypes.POINTER(ctypes.c_double)]
    t = np.ascontiguousarray(t_s, dtype=np.float64)
    out = np.empty(len(t))
    f(*(float(scenario[k]) for k in SCENARIO_KEYS), len(t), _dptr(t), _dptr(out))
    return out


def config_path(name):
    if os.path.sep in name or name.endswith(".ini"):
        return os.path.abspath(name)
    return os.path.join(CONFIG_DIR, name + ".ini")


def _dptr(a):
    return a.ctypes.data_as(ctypes.POINTER(ctypes.c_double))


def _iptr(a):
    return a.ctypes.data_as(ctypes.POINTER(ctypes.c_int32))


def initial_state(run):
    """Height, P2, P1 at the start: averaged over the quiet start of the run
    (before the first load change or actuator switch, at most 2 s), so sensor
    noise does not become an initial-state error."""
    t = run.t_s
    end = np.searchsorted(t, t[0] + 2.0)
    changes = [np.flatnonzero(np.abs(np.diff(run.load_n)) > 1.0)]
    changes += [np.flatnonzero(np.diff(v) != 0) for v in run.commands.values()]
    for c in changes:
        if c.size:
            end = min(end, int(c[0]) + 1)
    end = max(end, 1)
    out = []
    for sig in ("height_m", "p_spring_pa", "p_pipe_pa"):
        v = run.signals[sig][:end]
        v = v[np.isfinite(v)]
        out.append(float(np.mean(v)) if v.size else np.nan)
    return out


def _bind(f):
    """diag_simulate's signature (truth_simulate has the same)."""
    f.restype = ctypes.c_int
    f.argtypes = [ctypes.c_char_p, ctypes.c_int, ctypes.POINTER(ctypes.c_double),
                  ctypes.POINTER(ctypes.c_double), ctypes.POINTER(ctypes.c_int32), ctypes.c_int,
                  ctypes.POINTER(ctypes.c_double), ctypes.POINTER(ctypes.c_double),
                  ctypes.POINTER(ctypes.c_double), ctypes.POINTER(ctypes.c_int32),
                  ctypes.c_char_p, ctypes.c_int]
    return f


class CPlant(Simulator):
    def __init__(self, lib_path=None):
        self.lib = _library(lib_path or find_library())
        if self.lib.diag_abi_version() != ABI:
            raise DiagnoseInputError("libleveler_diag.so has another ABI version; rebuild it")
        self.simulate_fn = _bind(self.lib.diag_simulate)
        self.truth_fn = None   # the blind test's truth library, loaded when generate() is first called
        self.lib.diag_config_check.restype = ctypes.c_int
        self.lib.diag_config_check.argtypes = [ctypes.c_char_p, ctypes.c_char_p, ctypes.c_int]

    def configs(self):
        return sorted(os.path.splitext(os.path.basename(p))[0]
                      for p in glob.glob(os.path.join(CONFIG_DIR, "*.ini")))

    def check_config(self, name):
        path = config_path(name)
        if not os.path.isfile(path):
            raise DiagnoseInputError(f"--config: no plant config {name!r} ({path} does not exist; "
                                     f"known: {', '.join(self.configs())})")
        err = ctypes.create_string_buffer(512)
        if self.lib.diag_config_check(path.encode(), err, len(err)) != 0:
            raise DiagnoseInputError(err.value.decode(errors="replace"))

    def _call(self, config, t_s, load_n, commands, kind, values, init, fn=None):
        n = len(t_s)
        t = np.ascontiguousarray(t_s, dtype=np.float64)
        load = np.ascontiguousarray(load_n, dtype=np.float64)
        p = np.zeros(MAX_PARAMS)
        p[:len(values)] = values
        ini = np.ascontiguousarray(init, dtype=np.float64)
        out = np.empty((n, 4))
        cmd_out = np.empty((n, 4), dtype=np.int32)
        cmd = None
        if commands is not None:
            cmd = np.ascontiguousarray(np.stack([commands.get(c, np.zeros(n)) for c in COMMANDS], axis=1),
                                       dtype=np.int32)
        err = ctypes.create_string_buffer(512)
        rc = (fn or self.simulate_fn)(config_path(config).encode(), n, _dptr(t), _dptr(load),
                                    None if cmd is None else _iptr(cmd), kind, _dptr(p), _dptr(ini),
                                    _dptr(out), _iptr(cmd_out), err, len(err))
        if rc != 0:
            raise RuntimeError(f"C plant: {err.value.decode(errors='replace')}")
        return Trace(t, {s: out[:, i].copy() for i, s in enumerate(SIGNALS)},
                     {c: cmd_out[:, i].copy() for i, c in enumerate(COMMANDS)})

    def simulate(self, config, run, effect, params, mode):
        if effect:
            e = fx.get(effect)
            values = [params.get(q.name, q.nominal) for q in e.params]
            kind = e.effect_id
        else:
            values, kind = [], 0
        init = initial_state(run)
        if effect == "sensor_lag":
            # the log shows what the transducers read: the plant started at reading - offset
            init[0] -= params.get("h_offset_m", 0.0)
            init[1] -= params.get("p_offset_pa", 0.0)
        if mode != CLOSED_LOOP:
            return self._call(config, run.t_s, run.load_n, run.commands, kind, values, init)
        return self._closed_loop(config, run.t_s, run.load_n, kind, values, init)

    def _closed_loop(self, config, t_s, load_n, kind, values, init, fn=None):
        """The firmware ticks every 10 ms: simulate on that grid from the log's first
        time, holding the logged load, then read the trace at the log's own times."""
        tick = 0.01
        rel = t_s - t_s[0]
        if len(rel) > 1 and np.allclose(np.diff(rel), tick, atol=1e-6) and abs(rel[0]) < 1e-9:
            return self._call(config, np.round(rel, 2), load_n, None, kind, values, init, fn)
        grid = np.arange(0.0, rel[-1] + tick / 2, tick)
        idx = np.clip(np.searchsorted(rel, grid, side="right") - 1, 0, len(rel) - 1)
        tr = self._call(config, grid, np.asarray(load_n)[idx], None, kind, values, init, fn)
        back = np.clip(np.searchsorted(grid, rel, side="right") - 1, 0, len(grid) - 1)
        return Trace(t_s, {k: np.interp(rel, grid, v) for k, v in tr.signals.items()},
                     {k: v[back] for k, v in tr.commands.items()})

    def generate(self, config, t_s, load_n, truth_effect, truth_params, seed=0):
        """Closed loop with a truth variant of the blind test (libleveler_truth.so, same
        ids as the candidates): truth_params is the list of the variant's values."""
        if self.truth_fn is None:
            self.truth_fn = _bind(_library(find_truth_library()).truth_simulate)
        kind = 0 if truth_effect in (None, "none") else fx.get(truth_effect).effect_id
        return self._closed_loop(config, np.asarray(t_s, dtype=float), load_n, kind,
                                 list(truth_params or []), [np.nan] * 3, self.truth_fn)

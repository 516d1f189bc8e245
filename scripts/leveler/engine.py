"""The C engine's one binding (host_sim/diagnose/engine.h): libleveler_diag.so
found once (leveler.paths), its ABI checked once, every signature bound once
from one table. The diagnosis, the blind test, the PIL harness, the report and
leveler.config reach the C plant through here and nowhere else.

  Engine(path)          a config opened once: its resolved form (config_json),
                        its effects, its motor balance, runs (run), and the
                        PIL harness's tick-by-tick stepping (step_*)
  Engine.cached(path)   the same, one open handle per file version
  schedule helpers      the simulator's schedule rules without a plant

The library is looked up in $LEVELER_DIAG_LIB, then in the installed package
(pip install .: leveler/_lib), then in the build folders. The blind test's
build of the engine (libleveler_truth.so: the truth families as effect tables,
ENGINE_TRUTH / ENGINE_TRUTH2) is the same engine: pass its path as lib."""
import collections
import ctypes
import functools
import json
import os
import threading

import numpy as np

from . import paths
from .errors import InputError

ABI = 7                 # ENGINE_ABI of host_sim/diagnose/engine.h
CANDIDATES, TRUTH, TRUTH2 = 0, 1, 2     # the effect tables a request may name
EFFECTS_NOMINAL = 1     # engine_open's flag: the config's effects at their nominal values
MAX_MODELS = 2          # PLANT_FX_MAX_MODELS
MAX_PARAMS = 8          # PLANT_FX_MAX_PARAMS
MAX_SCHEDULE_ROWS = 1024
ERR_LEN = 512

_d, _i, _u16 = (ctypes.POINTER(t) for t in (ctypes.c_double, ctypes.c_int32, ctypes.c_uint16))
_p, _s, _int, _dbl = ctypes.c_void_p, ctypes.c_char_p, ctypes.c_int, ctypes.c_double


class _Request(ctypes.Structure):
    """engine_request (engine.h), field for field."""
    _fields_ = [("n", _int), ("t_s", _d), ("load_n", _d), ("commands", _i), ("p1_track", _d), ("p2_track", _d),
                ("n_writes", _int), ("write_t_s", _d), ("write_values", _i), ("init", _d),
                ("catalogue", _int), ("fx_kinds", _i), ("n_sets", _int), ("fx_params", _d)]


class _Result(ctypes.Structure):
    _fields_ = [("sensed", _d), ("actuators", _i)]


# name: (restype, argtypes): the whole C interface, bound once per library
_SIGNATURES = {
    "engine_abi_version": (_int, []),
    "engine_tick_s": (_dbl, []),
    "engine_open": (_p, [_s, _int, _s, _int]),
    "engine_close": (None, [_p]),
    "engine_config_json": (_int, [_p, _s, _int, _s, _int]),
    "engine_config_effects": (None, [_p, _i, _d]),
    "engine_motor_speed": (_dbl, [_p, _dbl, _dbl]),
    "engine_algorithm": (_int, [_p]),
    "engine_run": (_int, [_p, ctypes.POINTER(_Request), ctypes.POINTER(_Result), _s, _int]),
    "engine_step_open": (_int, [_p, _s, _int]),
    "engine_step_end_s": (_dbl, [_p]),
    "engine_step_counts": (None, [_p, _int, _u16]),
    "engine_step_decide": (None, [_p, _i, _i]),
    "engine_step_state": (None, [_p, _d]),
    "engine_step_advance": (None, [_p]),
    "engine_commission_registers": (_int, [_p, _int, _u16, _int, _u16, _int, _s, _int]),
    "engine_schedule_column": (_s, [_int]),
    "engine_schedule_column_output": (_int, [_int]),
    "engine_schedule_read": (_int, [_s, _int, _d, _d, _i, _s, _int]),
    "engine_schedule_apply": (_int, [_int, _d, _d, _i, _int, _d, _d, _i, _s, _int]),
    "engine_scenario_loads": (None, [_dbl] * 5 + [_int, _d, _d]),
}


# ctypes lets go of the GIL in a call, and the firmware in the loop is one per
# process (engine.h): runs, stepping and schedule_apply take turns, whatever the
# thread (a Dask worker of an existing cluster may run tasks in several)
_FIRMWARE = threading.RLock()


class EngineError(RuntimeError):
    """The library is missing, of another ABI, or refused a run (its message)."""


def find_library(env="LEVELER_DIAG_LIB", folder="diagnose", name="libleveler_diag.so", target="leveler_diag"):
    """The engine's library (or, with the blind test's arguments, its truth build)."""
    try:
        return paths.compiled(env, f"_lib/{name}", f"host_sim/{folder}/{name}",
                              f"build it with `cmake --build build/sim --target {target}`")
    except paths.NotFound as e:
        raise EngineError(str(e)) from None


def find_truth_library():
    """The blind test's build of the engine (host_sim/blindtest/), not part of the product."""
    return find_library("LEVELER_TRUTH_LIB", "blindtest", "libleveler_truth.so", "leveler_truth")


@functools.lru_cache(maxsize=None)
def library(path=None):
    """The engine's library by path (None: found), loaded and bound once, refused
    when built for another ABI (rebuild it)."""
    path = path or find_library()
    lib = ctypes.CDLL(path)
    lib.engine_abi_version.restype = _int
    if lib.engine_abi_version() != ABI:
        raise EngineError(f"{path} has ABI {lib.engine_abi_version()}, this code needs {ABI}: rebuild it")
    for name, (res, args) in _SIGNATURES.items():
        f = getattr(lib, name)
        f.restype, f.argtypes = res, args
    lib.path = path
    return lib


def dptr(a):
    return None if a is None else a.ctypes.data_as(_d)


def iptr(a):
    return None if a is None else a.ctypes.data_as(_i)


def _err():
    return ctypes.create_string_buffer(ERR_LEN)


def _msg(err):
    return err.value.decode(errors="replace")


def _f64(a):
    return None if a is None else np.ascontiguousarray(a, dtype=np.float64)


def _i32(a):
    return None if a is None else np.ascontiguousarray(a, dtype=np.int32)


class Engine:
    """A config opened once in the engine (None: the built-in thesis 900 lb one).
    effects_nominal: the config's own effects at their nominal values (the nominal
    plant step for step). lib: another build of the engine (the blind test's)."""

    def __init__(self, config_path=None, effects_nominal=False, lib=None):
        self.lib = library(lib)
        self.path = self.lib.path
        self.config_path = None if config_path is None else os.fspath(config_path)
        err = _err()
        arg = None if config_path is None else os.fsencode(config_path)
        self._h = self.lib.engine_open(arg, EFFECTS_NOMINAL if effects_nominal else 0, err, ERR_LEN)
        if not self._h:
            raise InputError(_msg(err))

    _open = collections.OrderedDict()
    CACHE = 64

    @classmethod
    def cached(cls, config_path, effects_nominal=False, lib=None):
        """One handle per (library, file, its modification time, flags), the last
        CACHE of them kept open: a config edited on disk is read again."""
        path = os.path.abspath(config_path)
        try:
            mtime = os.stat(path).st_mtime_ns
        except OSError as e:
            raise InputError(f"{path}: cannot open: {e.strerror}") from None
        key = (lib, path, mtime, effects_nominal)
        if key in cls._open:
            cls._open.move_to_end(key)
        else:
            cls._open[key] = cls(path, effects_nominal, lib)
            while len(cls._open) > cls.CACHE:
                cls._open.popitem(last=False)[1].close()
        return cls._open[key]

    def close(self):
        if getattr(self, "_h", None):
            self.lib.engine_close(self._h)
            self._h = None

    def __del__(self):
        self.close()

    # ---- the config ----

    def config_json(self):
        """The resolved config (SI) as the C loader reads it, as a dict."""
        err = _err()
        need = self.lib.engine_config_json(self._h, None, 0, err, ERR_LEN)
        buf = ctypes.create_string_buffer(max(need, 0) + 1)
        if need < 0 or self.lib.engine_config_json(self._h, buf, len(buf), err, ERR_LEN) < 0:
            raise EngineError(_msg(err))
        return json.loads(buf.value.decode())

    def effects(self):
        """The config's own effects: ids (MAX_MODELS, 0 = none) and their values
        (MAX_MODELS x MAX_PARAMS, SI)."""
        ids = np.zeros(MAX_MODELS, dtype=np.int32)
        vals = np.zeros((MAX_MODELS, MAX_PARAMS))
        self.lib.engine_config_effects(self._h, iptr(ids), dptr(vals))
        return ids, vals

    def motor_speed(self, p1_pa, duty):
        """The motor speed in balance at P1 with the compressor on a fraction duty of the time."""
        return float(self.lib.engine_motor_speed(self._h, float(p1_pa), float(duty)))

    @property
    def algorithm(self):
        return int(self.lib.engine_algorithm(self._h))

    # ---- runs ----

    def run(self, t_s, load_n, commands=None, p1_track=None, writes=None, init=None, catalogue=CANDIDATES,
            kinds=None, params=None, p2_track=None):
        """One run per parameter set. commands: n x 4 (compressor, spring, vent,
        acc) to replay, None for the firmware in the loop (then writes: schedule
        rows [(t_s, {register: value})] made through its register map). kinds:
        MAX_MODELS effect ids of the catalogue; params: one set (MAX_MODELS x
        MAX_PARAMS) or many (sets x MAX_MODELS x MAX_PARAMS). Returns sensed
        (sets x n x 4: height, P2, P1, P3) and actuators (sets x n x 4); one set
        given as one set: without the leading axis."""
        t, load = _f64(t_s), _f64(load_n)
        n = len(t)
        p = np.zeros((MAX_MODELS, MAX_PARAMS)) if params is None else _f64(params)
        one = p.ndim == 2
        p = np.ascontiguousarray(p.reshape(-1, MAX_MODELS, MAX_PARAMS))
        wt, wv = _writes(writes)
        # named, so the arrays outlive the call that reads them through pointers
        cmd, track, track2, start = _i32(commands), _f64(p1_track), _f64(p2_track), _f64(init)
        ids = _i32(np.zeros(MAX_MODELS) if kinds is None else kinds)
        _sizes(n, load=(load, (n,)), commands=(cmd, (n, 4)), p1_track=(track, (n,)), p2_track=(track2, (n,)),
               init=(start, (5,)),
               kinds=(ids, (MAX_MODELS,)))
        rq = _Request(n, dptr(t), dptr(load), iptr(cmd), dptr(track), dptr(track2), 0 if wt is None else len(wt),
                      dptr(wt), iptr(wv), dptr(start), catalogue, iptr(ids), len(p), dptr(p))
        sensed = np.empty((len(p), n, 4))
        act = np.empty((len(p), n, 4), dtype=np.int32)
        err = _err()
        with _FIRMWARE:
            rc = self.lib.engine_run(self._h, ctypes.byref(rq), ctypes.byref(_Result(dptr(sensed), iptr(act))),
                                     err, ERR_LEN)
        if rc != 0:
            raise EngineError(f"C plant: {_msg(err)}")
        return (sensed[0], act[0]) if one else (sensed, act)

    # ---- one tick at a time (the PIL harness) ----

    def step_open(self):
        """The plant at the config's initial state at t = 0; the config's algorithm."""
        err = _err()
        alg = self.lib.engine_step_open(self._h, err, ERR_LEN)
        if alg < 0:
            raise EngineError(_msg(err))
        self.end_s = float(self.lib.engine_step_end_s(self._h))
        return alg

    def step_counts(self, noisy=True):
        """Height, P2, P1, P3 as 12-bit counts; noisy: one draw of the config's seeded noise."""
        c = (ctypes.c_uint16 * 4)()
        self.lib.engine_step_counts(self._h, int(noisy), c)
        return list(c)

    def step_state(self):
        """(t_s, height_m, p_spring_pa, p_pipe_pa, p_acc_pa, load_n) of the tick decided last."""
        s = (ctypes.c_double * 6)()
        self.lib.engine_step_state(self._h, s)
        return tuple(s)

    def step(self, outputs):
        """One tick: the actuators (compressor, spring, vent, acc; the config's
        [initial] ones at the first tick) and the scheduled load, then 10 ms of
        RK4. Returns the state at the tick's start and the actuators applied."""
        applied = (ctypes.c_int32 * 4)()
        with _FIRMWARE:
            self.lib.engine_step_decide(self._h, (ctypes.c_int32 * 4)(*[int(bool(o)) for o in outputs]), applied)
            st = self.step_state()
            self.lib.engine_step_advance(self._h)
        return st, tuple(bool(v) for v in applied)

    def commission_registers(self, algorithm=0, size=4096, max_runs=32):
        """[(first address, [values])]: the holding registers after commissioning, as FC 16 runs."""
        runs = (ctypes.c_uint16 * (2 * max_runs))()
        values = (ctypes.c_uint16 * size)()
        err = _err()
        with _FIRMWARE:
            n = self.lib.engine_commission_registers(self._h, int(algorithm), runs, max_runs, values, size, err,
                                                     ERR_LEN)
        if n < 0:
            raise EngineError(_msg(err))
        return [(runs[2 * k], list(values[runs[2 * k]:runs[2 * k] + runs[2 * k + 1]])) for k in range(n)]


def _sizes(n, **given):
    """The C side reads each array at the size the request implies: anything
    else is refused here, named, rather than read past its end."""
    for name, (a, want) in given.items():
        if a is not None and a.shape != want:
            raise EngineError(f"request: {name} has shape {a.shape}, {n} samples need {want}")


def config_json(path=None):
    """The resolved config (SI; the built-in thesis 900 lb one for None) as the C
    loader reads it, as a dict; InputError with the loader's file:line message."""
    return Engine(path).config_json()


# ---- the simulator's schedule rules, without a plant ----

@functools.lru_cache(maxsize=None)
def tick_s():
    """The simulator's tick in s (SIM_TICK_S: the firmware's LEVELER_TICK_MS)."""
    return float(library().engine_tick_s())


def tick_grid(end_s):
    """The simulator's tick times from 0 to end_s (the tick at end_s included, 1 us of
    slack against rounding), rounded to the 10 ms they stand for."""
    return np.round(np.arange(0.0, end_s + 1e-6, tick_s()), 2)


SCENARIO_KEYS = ("base_load_n", "step_load_n", "step_on_s", "step_off_s", "end_s")


def scenario_loads(t_s, scenario):
    """The load over each tick from t_s[i] of a scenario (dict of the config's
    [scenario] keys SCENARIO_KEYS), by the simulator's rule."""
    t = _f64(t_s)
    out = np.empty(len(t))
    library().engine_scenario_loads(*(float(scenario[k]) for k in SCENARIO_KEYS), len(t), dptr(t), dptr(out))
    return out


@functools.lru_cache(maxsize=None)
def schedule_columns():
    """The register columns a schedule file may have (mode and the manual requests),
    named as the register map names them, in the C table's order (stepper.h)."""
    lib, out = library(), []
    while (name := lib.engine_schedule_column(len(out))) is not None:
        out.append(name.decode())
    return tuple(out)


@functools.lru_cache(maxsize=None)
def schedule_column_outputs():
    """{manual request column: the actuator's index (compressor, spring, vent, acc)}."""
    lib = library()
    return {c: lib.engine_schedule_column_output(j) for j, c in enumerate(schedule_columns())
            if lib.engine_schedule_column_output(j) >= 0}


def read_schedule(path):
    """A schedule file by the simulator's one parser (host_sim/sim/schedule.c):
    [(t_s, load_n, {register: value})] (the dict holds the row's writes, may be
    empty), the end time. InputError names the file, line and field."""
    cols = schedule_columns()
    t, load = np.empty(MAX_SCHEDULE_ROWS), np.empty(MAX_SCHEDULE_ROWS)
    vals = np.empty((MAX_SCHEDULE_ROWS, len(cols)), dtype=np.int32)
    err = _err()
    n = library().engine_schedule_read(os.fsencode(path), MAX_SCHEDULE_ROWS, dptr(t), dptr(load), iptr(vals), err,
                                       ERR_LEN)
    if n < 0:
        raise InputError(_msg(err))
    rows = [(float(t[i]), float(load[i]), {c: int(vals[i, j]) for j, c in enumerate(cols) if vals[i, j] >= 0})
            for i in range(n)]
    return rows, rows[-1][0]


def _write_values(rows):
    """The register cells of rows [(t_s, {register: value})] as the C side takes
    them: rows x columns in schedule_columns()' order, -1 = no write."""
    cols = schedule_columns()
    vals = np.full((len(rows), len(cols)), -1, dtype=np.int32)
    for i, (_, w) in enumerate(rows):
        for name, v in w.items():
            vals[i, cols.index(name)] = v
    return vals


def _writes(writes):
    """A run's register writes as (times, values), or (None, None) for none."""
    writes = list(writes or [])
    if not writes:
        return None, None
    return _f64([w[0] for w in writes]), _write_values(writes)


def schedule_apply(t_s, steps):
    """A schedule [(t_s, load_n[, {register: value}])] at the times t_s (increasing) by
    the simulator's own rules: the load over each tick from t_s[i], and {register:
    array} what each schedule column's register holds in the firmware's register
    map after that tick's writes (mode and manual requests)."""
    rows = [(float(r[0]), dict(r[2]) if len(r) > 2 else {}) for r in steps]
    rt, vals = _f64([r[0] for r in rows]), _write_values(rows)
    rl = _f64([float(r[1]) for r in steps])
    t = _f64(t_s)
    load = np.empty(len(t))
    regs = np.empty((len(t), len(schedule_columns())), dtype=np.int32)
    err = _err()
    with _FIRMWARE:
        rc = library().engine_schedule_apply(len(rows), dptr(rt), dptr(rl), iptr(vals), len(t), dptr(t),
                                             dptr(load), iptr(regs), err, ERR_LEN)
    if rc != 0:
        raise InputError(f"schedule: {_msg(err)}")
    return load, {c: regs[:, j].copy() for j, c in enumerate(schedule_columns())}

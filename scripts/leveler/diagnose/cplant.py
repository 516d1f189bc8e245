"""The project's C plant through ctypes (host_sim/diagnose/diag_shim.c, host_sim/plant/effects*.c).

The shared library `libleveler_diag.so` is built without sanitizers by
host_sim/diagnose/CMakeLists.txt. It is looked up in $LEVELER_DIAG_LIB, then in
the installed package (pip install .), then in the project's build folders
(build/sim, build/bench, build/test): leveler/paths.py.
"""
import ctypes
import functools
import glob
import hashlib
import tempfile
import os

import numpy as np

from . import effects as fx
from .errors import DiagnoseInputError
from .model import CLOSED_LOOP, Simulator, Trace

from leveler import engine, paths

# the names --config takes: the checkout's host_sim/configs, else the installed package's copy
CONFIG_DIR = paths.data("host_sim/configs", "configs")
ABI = engine.ABI
MAX_PARAMS = 8
SIGNALS = ("height_m", "p_spring_pa", "p_pipe_pa", "p_acc_pa")
COMMANDS = ("compressor", "spring_valve", "vent_valve", "acc_valve")
SCENARIO_KEYS = ("base_load_n", "step_load_n", "step_on_s", "step_off_s", "end_s")


def find_library(*args, **kw):
    try:
        return engine.find_library(*args, **kw)
    except engine.EngineError as e:
        raise DiagnoseInputError(str(e)) from None


def find_truth_library():
    """The blind test's truth variants (host_sim/blindtest/), not part of the product."""
    return find_library("LEVELER_TRUTH_LIB", "blindtest", "libleveler_truth.so", "leveler_truth")


_library = engine.load


def _diag_library(path=None):
    """libleveler_diag.so through the one binding (leveler.engine)."""
    try:
        return engine.library(path)
    except engine.EngineError as e:
        raise DiagnoseInputError(str(e)) from None


def scenario_loads(t_s, scenario):
    """The load over each tick from t_s[i] of a scenario (dict of the config's [scenario]
    keys base_load_n, step_load_n, step_on_s, step_off_s, end_s), by the simulator's rule."""
    f = _diag_library().diag_scenario_loads
    f.restype = None
    f.argtypes = [ctypes.c_double] * 5 + [ctypes.c_int, ctypes.POINTER(ctypes.c_double),
                                          ctypes.POINTER(ctypes.c_double)]
    t = np.ascontiguousarray(t_s, dtype=np.float64)
    out = np.empty(len(t))
    f(*(float(scenario[k]) for k in SCENARIO_KEYS), len(t), _dptr(t), _dptr(out))
    return out


@functools.lru_cache(maxsize=None)
def tick_s():
    """The simulator's tick in s (SIM_TICK_S: the firmware's LEVELER_TICK_MS)."""
    f = _diag_library().diag_tick_s
    f.restype = ctypes.c_double
    return float(f())


def tick_grid(end_s):
    """The simulator's tick times from 0 to end_s (the tick at end_s included, 1 us of
    slack against rounding), rounded to the 10 ms they stand for."""
    return np.round(np.arange(0.0, end_s + 1e-6, tick_s()), 2)


MAX_SCHEDULE_ROWS = 1024


@functools.lru_cache(maxsize=None)
def schedule_columns():
    """The register columns a schedule file may have (mode and the manual requests),
    named as the register map names them, in the C table's order (stepper.h)."""
    lib = _diag_library()
    lib.diag_schedule_column.restype = ctypes.c_char_p
    lib.diag_schedule_column.argtypes = [ctypes.c_int]
    out, j = [], 0
    while (name := lib.diag_schedule_column(j)) is not None:
        out.append(name.decode())
        j += 1
    return tuple(out)


@functools.lru_cache(maxsize=None)
def request_commands():
    """{manual request column: the actuator it asks for, named as COMMANDS (the trace's
    commands)}, from the C table of schedule columns."""
    f = _diag_library().diag_schedule_column_output
    f.restype = ctypes.c_int
    f.argtypes = [ctypes.c_int]
    return {c: COMMANDS[f(j)] for j, c in enumerate(schedule_columns()) if f(j) >= 0}


def read_schedule(path):
    """A schedule file by the simulator's one parser (host_sim/sim/schedule.c):
    [(t_s, load_n, {register: value})] (the dict holds the row's writes, may be
    empty), the end time. Errors name the file, line and field."""
    lib = _diag_library()
    f = lib.diag_schedule_read
    f.restype = ctypes.c_int
    f.argtypes = [ctypes.c_char_p, ctypes.c_int, ctypes.POINTER(ctypes.c_double), ctypes.POINTER(ctypes.c_double),
                  ctypes.POINTER(ctypes.c_int32), ctypes.c_char_p, ctypes.c_int]
    cols = schedule_columns()
    t, load = np.empty(MAX_SCHEDULE_ROWS), np.empty(MAX_SCHEDULE_ROWS)
    vals = np.empty((MAX_SCHEDULE_ROWS, len(cols)), dtype=np.int32)
    err = ctypes.create_string_buffer(512)
    n = f(os.fsencode(path), MAX_SCHEDULE_ROWS, _dptr(t), _dptr(load), _iptr(vals), err, len(err))
    if n < 0:
        raise DiagnoseInputError(err.value.decode(errors="replace"))
    rows = [(float(t[i]), float(load[i]), {c: int(vals[i, j]) for j, c in enumerate(cols) if vals[i, j] >= 0})
            for i in range(n)]
    return rows, rows[-1][0]


@functools.lru_cache(maxsize=None)
def _writes_fn(lib):
    f = lib.diag_set_schedule_writes
    f.restype = ctypes.c_int
    f.argtypes = [ctypes.c_int, ctypes.POINTER(ctypes.c_double), ctypes.POINTER(ctypes.c_int32),
                  ctypes.c_char_p, ctypes.c_int]
    return f


def _write_values(rows):
    """The register cells of schedule rows [(t_s, {register: value})] as the C side
    takes them: rows x columns in schedule_columns()' order, -1 = no write."""
    cols = schedule_columns()
    vals = np.full((len(rows), len(cols)), -1, dtype=np.int32)
    for i, (_, w) in enumerate(rows):
        for name, v in w.items():
            vals[i, cols.index(name)] = v
    return vals


def _set_writes(lib, writes):
    """The register writes [(t_s, {register: value})] of the next closed-loop run (diag_shim.c)."""
    f = _writes_fn(lib)
    writes = list(writes or [])
    if not writes:
        f(0, None, None, None, 0)
        return
    t = np.ascontiguousarray([w[0] for w in writes], dtype=np.float64)
    vals = _write_values(writes)
    err = ctypes.create_string_buffer(512)
    if f(len(writes), _dptr(t), _iptr(vals), err, len(err)) != 0:
        raise RuntimeError(f"C plant: {err.value.decode(errors='replace')}")


@functools.lru_cache(maxsize=None)
def _apply_fn(lib):
    f = lib.diag_schedule_apply
    f.restype = ctypes.c_int
    f.argtypes = [ctypes.c_int, ctypes.POINTER(ctypes.c_double), ctypes.POINTER(ctypes.c_double),
                  ctypes.POINTER(ctypes.c_int32), ctypes.c_int, ctypes.POINTER(ctypes.c_double),
                  ctypes.POINTER(ctypes.c_double), ctypes.POINTER(ctypes.c_int32), ctypes.c_char_p, ctypes.c_int]
    return f


def schedule_apply(t_s, steps):
    """A schedule [(t_s, load_n[, {register: value}])] at the times t_s (increasing) by
    the simulator's own rules (diag_schedule_apply): the load over each tick from
    t_s[i], and {register: array} what each schedule column's register holds in the
    firmware's register map after that tick's writes (mode and manual requests)."""
    lib = _diag_library()
    rows = [(float(r[0]), dict(r[2]) if len(r) > 2 else {}) for r in steps]
    rt = np.ascontiguousarray([r[0] for r in rows], dtype=np.float64)
    rl = np.ascontiguousarray([float(r[1]) for r in steps], dtype=np.float64)
    vals = _write_values(rows)
    t = np.ascontiguousarray(t_s, dtype=np.float64)
    load = np.empty(len(t))
    regs = np.empty((len(t), len(schedule_columns())), dtype=np.int32)
    err = ctypes.create_string_buffer(512)
    if _apply_fn(lib)(len(rows), _dptr(rt), _dptr(rl), _iptr(vals), len(t), _dptr(t), _dptr(load), _iptr(regs),
                      err, len(err)) != 0:
        raise DiagnoseInputError(f"schedule: {err.value.decode(errors='replace')}")
    return load, {c: regs[:, j].copy() for j, c in enumerate(schedule_columns())}


def config_path(name):
    if os.path.sep in name or name.endswith(".ini"):
        return os.path.abspath(name)
    return os.path.join(CONFIG_DIR, name + ".ini")


def _dptr(a):
    return a.ctypes.data_as(ctypes.POINTER(ctypes.c_double))


def _iptr(a):
    return a.ctypes.data_as(ctypes.POINTER(ctypes.c_int32))


def _effect_arrays(kind, values):
    """diag_simulate's fx_kinds and fx_params: an id with its list of values, or a
    list of up to fx.MAX_AT_ONCE ids with a list of lists."""
    if np.isscalar(kind):
        kind, values = ([kind], [values]) if kind else ([], [])
    kinds = np.zeros(fx.MAX_AT_ONCE, dtype=np.int32)
    p = np.zeros((fx.MAX_AT_ONCE, MAX_PARAMS))
    for i, (k, v) in enumerate(zip(kind, values)):
        kinds[i] = k
        p[i, :len(v)] = v
    return kinds, np.ascontiguousarray(p.ravel())


QUIET_MAX_S = 2.0       # the quiet start: at most this long
DUTY_WINDOW_S = 1.0     # compressor duty at the start, for the motor speed
FINE_TICK_S = 0.01      # replay grid for coarse or jittered logs
CHATTER_SWITCHES = 4    # compressor switches within a second that make a stretch "chatter"
CHATTER_SMOOTH_S = 0.1  # the P1 a chattering stretch regulates to: logged P1 averaged over +-this
OMEGA_WINDOW_S = 3.0    # the motor speed is fitted to P1 over at most this long


def _quiet_end(run):
    """Index where the quiet start ends: the first load change or valve switch
    (at most QUIET_MAX_S). Compressor switching does not end it: with
    algorithm 2 at the accumulator's charge limit it may switch every tick."""
    t = run.t_s
    end = int(np.searchsorted(t, t[0] + QUIET_MAX_S))
    changes = [np.flatnonzero(np.abs(np.diff(run.load_n)) > 1.0)]
    changes += [np.flatnonzero(np.diff(v) != 0) for k, v in run.commands.items() if k != "compressor"]
    for c in changes:
        if c.size:
            end = min(end, int(c[0]) + 1)
    return max(end, 1)


def _start_value(t, v, end, trend):
    """Value at t[0] from the quiet start: the mean, or with `trend` the intercept
    of a straight line (a pipe the compressor fills while the valves are shut)."""
    ok = np.isfinite(v[:end])
    if not ok.any():
        return np.nan
    tt, vv = t[:end][ok], v[:end][ok]
    if trend and len(vv) >= 8 and np.ptp(tt) > 0:
        slope, icpt = np.polyfit(tt - t[0], vv, 1)
        return float(icpt)
    return float(np.mean(vv))


def initial_state(run):
    """Height, P2, P1, P3 at the start, averaged over the quiet start so sensor
    noise does not become an initial-state error, and the compressor's duty
    over the first second (the motor speed is never logged). A P1 column that
    is empty takes P3 when the accumulator valve is open, else P2 (the pipe
    equalises with what it is open to)."""
    t, end = run.t_s, _quiet_end(run)
    sig = run.signals
    h = _start_value(t, sig["height_m"], end, False)
    p2 = _start_value(t, sig["p_spring_pa"], end, False)
    p3 = _start_value(t, sig.get("p_acc_pa", np.full(len(t), np.nan)), end, True)
    p1 = _start_value(t, sig["p_pipe_pa"], end, True)
    acc_open = bool(run.commands.get("acc_valve", np.zeros(1))[0]) if run.commands else False
    if not np.isfinite(p1):
        p1 = p3 if acc_open and np.isfinite(p3) else p2
    comp = run.commands.get("compressor") if run.commands else None
    duty = 0.0
    if comp is not None and len(comp):
        n = max(1, int(np.searchsorted(t, t[0] + DUTY_WINDOW_S)))
        duty = float(np.mean(np.asarray(comp[:n]) != 0))
    return [h, p2, p1, p3], duty


def nearest_index(rel, grid):
    """For each grid time the index of the nearest sample of rel: a switch seen
    between two samples is placed halfway between them (an edge is only known
    within a sample)."""
    idx = np.clip(np.searchsorted(rel, grid), 0, len(rel) - 1)
    prev = np.clip(idx - 1, 0, len(rel) - 1)
    nearer_prev = np.abs(grid - rel[prev]) <= np.abs(rel[idx] - grid)
    idx = np.where(nearer_prev, prev, idx)
    return idx


def _window_counts(t, events, half):
    """For each time in t: how many of the sorted event times lie within +-half."""
    return np.searchsorted(events, t + half) - np.searchsorted(events, t - half)


def chatter_track(run):
    """Where the logged compressor chatters (CHATTER_SWITCHES or more switches within
    a second: algorithm 2 at the accumulator's charge limit, where sensor noise alone
    flips the rule), the P1 the replay's compressor regulates to: the logged P1
    averaged over +-CHATTER_SMOOTH_S. A log slower than the chatter does not hold its
    pattern, and replaying the samples open loop would integrate the wrong duty into
    the pipe (the rig's loop corrects it). None elsewhere. Used for logs slower than
    the tick only: a tick-rate log holds every switch, and its exact replay beats
    regulating (measured on the blind test's accumulator logs)."""
    comp = run.commands.get("compressor") if run.commands else None
    p1 = run.signals.get("p_pipe_pa")
    if comp is None or p1 is None or not np.isfinite(p1).mean() > 0.5:
        return None
    t = run.t_s
    t_sw = t[1:][np.diff(np.asarray(comp, dtype=int)) != 0]
    chatter = _window_counts(t, t_sw, 0.5) >= CHATTER_SWITCHES
    if not chatter.any():
        return None
    ok = np.isfinite(p1)
    csum = np.concatenate([[0.0], np.cumsum(np.where(ok, p1, 0.0))])
    cnt = np.concatenate([[0], np.cumsum(ok)])
    lo = np.searchsorted(t, t - CHATTER_SMOOTH_S)
    hi = np.searchsorted(t, t + CHATTER_SMOOTH_S, side="right")
    n = cnt[hi] - cnt[lo]
    smooth = np.where(n > 0, (csum[hi] - csum[lo]) / np.maximum(n, 1), np.nan)
    return np.where(chatter, smooth, np.nan)


def is_fine(t_s, tick=FINE_TICK_S):
    rel = t_s - t_s[0]
    return len(rel) > 1 and np.allclose(np.diff(rel), tick, atol=1e-6)


def _bind(f):
    """diag_simulate's signature (truth_simulate has the same)."""
    f.restype = ctypes.c_int
    f.argtypes = [ctypes.c_char_p, ctypes.c_int, ctypes.POINTER(ctypes.c_double),
                  ctypes.POINTER(ctypes.c_double), ctypes.POINTER(ctypes.c_int32),
                  ctypes.POINTER(ctypes.c_double), ctypes.POINTER(ctypes.c_int32),
                  ctypes.POINTER(ctypes.c_double), ctypes.POINTER(ctypes.c_double),
                  ctypes.POINTER(ctypes.c_double), ctypes.POINTER(ctypes.c_int32),
                  ctypes.c_char_p, ctypes.c_int]
    return f


class CPlant(Simulator):
    honours_start_shift = True

    def __init__(self, lib_path=None):
        self.lib = _diag_library(lib_path)
        self.simulate_fn = _bind(self.lib.diag_simulate)
        self.truth_fn = None   # the blind test's truth library, loaded when generate() is first called
        self.truth_lib = None
        self.lib.diag_motor_speed.restype = ctypes.c_double
        self.lib.diag_motor_speed.argtypes = [ctypes.c_char_p, ctypes.c_double, ctypes.c_double,
                                              ctypes.c_char_p, ctypes.c_int]
        self._motor_cache = {}
        self._omega_cache = {}
        self.lib.diag_config_check.restype = ctypes.c_int
        self.lib.diag_config_check.argtypes = [ctypes.c_char_p, ctypes.c_char_p, ctypes.c_int]
        self.lib.diag_config_effects.restype = ctypes.c_int
        self.lib.diag_config_effects.argtypes = [ctypes.c_char_p, ctypes.POINTER(ctypes.c_int32),
                                                 ctypes.POINTER(ctypes.c_double), ctypes.c_char_p, ctypes.c_int]
        self._config_fx = {}
        self._twins = None    # TemporaryDirectory of the configs with their effects at nominal (effects_off)

    def config_effects(self, config):
        """The config's own effects ([effect.NAME] sections, which the C plant runs on
        every call): {name: {parameter: value}}, cached by file and time."""
        path = config_path(config)
        key = (path, os.stat(path).st_mtime_ns)
        if key not in self._config_fx:
            ids = np.zeros(fx.MAX_AT_ONCE, dtype=np.int32)
            vals = np.zeros(fx.MAX_AT_ONCE * MAX_PARAMS)
            err = ctypes.create_string_buffer(512)
            if self.lib.diag_config_effects(path.encode(), _iptr(ids), _dptr(vals), err, len(err)) != 0:
                raise DiagnoseInputError(err.value.decode(errors="replace"))
            out = {}
            for i, k in enumerate(ids):
                if k:
                    e = fx.BY_ID[int(k)]
                    out[e.name] = {q.name: float(vals[i * MAX_PARAMS + j]) for j, q in enumerate(e.params)}
            self._config_fx[key] = out
        return self._config_fx[key]

    def effects_off(self, config):
        """config itself, or for one with effects a twin that sets each of their parameters
        to its nominal value: the nominal plant, bit for bit (an effect at its nominal values
        changes nothing), for what is estimated on the nominal plant (the start state)."""
        own = self.config_effects(config)
        if not own:
            return config
        # removed with this simulator (or at exit), not left in /tmp
        self._twins = self._twins or tempfile.TemporaryDirectory(prefix="leveler-effects-off-")
        text = f"[config]\ninclude = {config_path(config)}\n" + "".join(
            f"\n[effect.{name}]\n" + "".join(f"{q.name} = {q.nominal!r}\n" for q in fx.get(name).params)
            for name in own)
        path = os.path.join(self._twins.name, hashlib.sha1(text.encode()).hexdigest()[:16] + ".ini")
        if not os.path.exists(path):
            with open(path + ".tmp", "w") as fh:
                fh.write(text)
            os.replace(path + ".tmp", path)
        return path

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

    def _call(self, config, t_s, load_n, commands, kind, values, init, track=None, fn=None):
        """kind: an effect id (0 = none) and values its list, or up to two ids and
        a list of lists (two effects at once)."""
        n = len(t_s)
        t = np.ascontiguousarray(t_s, dtype=np.float64)
        load = np.ascontiguousarray(load_n, dtype=np.float64)
        kinds, p = _effect_arrays(kind, values)
        ini = np.ascontiguousarray(init, dtype=np.float64)
        out = np.empty((n, 4))
        cmd_out = np.empty((n, 4), dtype=np.int32)
        cmd = None
        if commands is not None:
            cmd = np.ascontiguousarray(np.stack([commands.get(c, np.zeros(n)) for c in COMMANDS], axis=1),
                                       dtype=np.int32)
        trk = None if track is None else np.ascontiguousarray(track, dtype=np.float64)
        err = ctypes.create_string_buffer(512)
        rc = (fn or self.simulate_fn)(config_path(config).encode(), n, _dptr(t), _dptr(load),
                                      None if cmd is None else _iptr(cmd), None if trk is None else _dptr(trk),
                                      _iptr(kinds), _dptr(p), _dptr(ini),
                                    _dptr(out), _iptr(cmd_out), err, len(err))
        if rc != 0:
            raise RuntimeError(f"C plant: {err.value.decode(errors='replace')}")
        return Trace(t, {s: out[:, i].copy() for i, s in enumerate(SIGNALS)},
                     {c: cmd_out[:, i].copy() for i, c in enumerate(COMMANDS)})

    def motor_speed(self, config, p1_pa, duty):
        """The motor speed in balance at the start (plant_motor_steady_speed)."""
        key = (config, round(float(p1_pa), 0), round(duty, 3))
        if key not in self._motor_cache:
            err = ctypes.create_string_buffer(512)
            w = self.lib.diag_motor_speed(config_path(config).encode(), float(p1_pa), float(duty), err, len(err))
            if w < 0.0:
                raise RuntimeError(f"C plant: {err.value.decode(errors='replace')}")
            self._motor_cache[key] = w
        return self._motor_cache[key]

    def start_motor_speed(self, config, run, init, duty):
        """The motor speed at the log's start, which no log holds, and a correction
        of the starting P1. With the compressor switched on in the first seconds and
        P1 logged, both are fitted to how P1 moves there: the nominal plant replayed
        with the logged commands over the first OMEGA_WINDOW_S (up to the first load
        change) for a grid of speeds, each with the constant shift of P1 that fits
        best, refined by a parabola. Otherwise the speed in balance for the
        compressor's duty (0 when it is off: a motor at rest). Returns (speed, shift)."""
        comp = run.commands.get("compressor") if run.commands else None
        key = (config, run.path, hash(run.signals["p_pipe_pa"].tobytes()),
               None if comp is None else hash(np.asarray(comp).tobytes()))
        if key in self._omega_cache:
            return self._omega_cache[key]
        out = (self.motor_speed(config, init[2], duty) if np.isfinite(init[2]) else 0.0, 0.0)
        t = run.t_s
        n = int(np.searchsorted(t, t[0] + OMEGA_WINDOW_S))
        load_change = np.flatnonzero(np.abs(np.diff(run.load_n[:n])) > 1.0)
        n = int(load_change[0]) + 1 if load_change.size else n
        p1 = run.signals["p_pipe_pa"][:n]
        if comp is not None and np.any(comp[:n]) and np.isfinite(p1).sum() > 10 and n > 10:
            grid = np.linspace(0.0, max(self.motor_speed(config, init[2], 1.0), 1.0) * 1.5, 13)
            cmds = {k: np.asarray(v[:n]) for k, v in run.commands.items()}
            cost, shift = [], []
            for w in grid:
                r = self._call(config, t[:n], run.load_n[:n], cmds, 0, [], init + [w]).signals["p_pipe_pa"] - p1
                shift.append(-float(np.nanmean(r)))
                cost.append(float(np.nanvar(r)))
            k = int(np.argmin(cost))
            step = 0.0
            if 0 < k < len(grid) - 1:
                den = cost[k - 1] - 2 * cost[k] + cost[k + 1]
                step = 0.5 * (cost[k - 1] - cost[k + 1]) / den if den > 0 else 0.0
            out = (float(grid[k] + step * (grid[1] - grid[0])), shift[k])
        self._omega_cache[key] = out
        return out

    def start_state(self, config, run, effect=None, params=None):
        """The 5 initial values diag_simulate takes, estimated from the log."""
        init, duty = initial_state(run)
        # on the nominal plant, whether the effects are asked for or in the config
        omega, p1_shift = self.start_motor_speed(self.effects_off(config), run, list(init), duty)
        init[2] += p1_shift
        params = params or {}
        dh, dp = getattr(run, "start_shift", (0.0, 0.0))
        init[0] += dh
        init[1] += dp
        lag = self.config_effects(config).get("sensor_lag")
        if lag is not None:
            effect, params = "sensor_lag", lag
        if "sensor_lag" in fx.parts(effect):
            # the log shows what the transducers read: the plant started at reading - offset
            init[0] -= params.get("h_offset_m", 0.0)
            init[1] -= params.get("p_offset_pa", 0.0)
        return init + [omega]

    def simulate(self, config, run, effect, params, mode):
        """effect: a name, a pair "a+b" or None."""
        singles = [fx.get(e) for e in fx.parts(effect)]
        kind = [e.effect_id for e in singles]
        values = [[params.get(q.name, q.nominal) for q in e.params] for e in singles]
        init = self.start_state(config, run, effect, params)
        if mode == CLOSED_LOOP:
            return self._closed_loop(config, run.t_s, run.load_n, kind, values, init,
                                     writes=getattr(run, "writes", None))
        if is_fine(run.t_s):      # the tick's own log: every switch is there, replayed as is
            return self._call(config, run.t_s, run.load_n, run.commands, kind, values, init)
        return self._replay_fine(config, run, kind, values, init, chatter_track(run))

    def _replay_fine(self, config, run, kind, values, init, track=None):
        """A coarse or jittered log: replay on the 10 ms grid with each switch halfway
        between the samples that bracket it, read back at the log's times."""
        rel = run.t_s - run.t_s[0]
        grid = np.round(np.arange(0.0, rel[-1] + FINE_TICK_S / 2, FINE_TICK_S), 6)
        idx = nearest_index(rel, grid)
        cmds = {k: np.asarray(v)[idx] for k, v in run.commands.items()}
        if track is not None:
            track = track[idx]      # the nearest sample's (already smoothed) value
        tr = self._call(config, grid, np.asarray(run.load_n)[idx], cmds, kind, values, init, track)
        back = nearest_index(grid, rel)
        return Trace(run.t_s, {k: np.interp(rel, grid, v) for k, v in tr.signals.items()},
                     {k: v[back] for k, v in tr.commands.items()})

    def _closed_loop(self, config, t_s, load_n, kind, values, init, fn=None, writes=None):
        """The firmware ticks every 10 ms: simulate on that grid from the log's first
        time, holding the logged load, then read the trace at the log's own times.
        writes: a schedule's register writes [(t_s from the start, {register: value})],
        made through the firmware's register map during the run."""
        tick = tick_s()
        rel = t_s - t_s[0]
        lib = self.truth_lib if fn is not None and fn is self.truth_fn else self.lib
        if len(rel) > 1 and np.allclose(np.diff(rel), tick, atol=1e-6) and abs(rel[0]) < 1e-9:
            _set_writes(lib, writes)
            return self._call(config, np.round(rel, 2), load_n, None, kind, values, init, fn=fn)
        grid = np.arange(0.0, rel[-1] + tick / 2, tick)
        idx = np.clip(np.searchsorted(rel, grid, side="right") - 1, 0, len(rel) - 1)
        _set_writes(lib, writes)
        tr = self._call(config, grid, np.asarray(load_n)[idx], None, kind, values, init, fn=fn)
        back = np.clip(np.searchsorted(grid, rel, side="right") - 1, 0, len(grid) - 1)
        return Trace(t_s, {k: np.interp(rel, grid, v) for k, v in tr.signals.items()},
                     {k: v[back] for k, v in tr.commands.items()})

    def generate(self, config, t_s, load_n, truth_effect, truth_params, seed=0, writes=None):
        """Closed loop with a truth variant of the blind test (libleveler_truth.so, same
        ids as the candidates): truth_params is the list of the variant's values (for
        a pair "a+b", a list of the two lists). The rig starts at rest: platform
        still, motor stopped. writes: a schedule's register writes (mode, manual
        requests) as in _closed_loop."""
        if self.truth_fn is None:
            self.truth_lib = _library(find_truth_library())
            self.truth_fn = _bind(self.truth_lib.truth_simulate)
        names = fx.parts(truth_effect)
        kind = [fx.get(e).effect_id for e in names]
        values = list(truth_params or []) if len(names) > 1 else [list(truth_params or [])] * len(names)
        return self._closed_loop(config, np.asarray(t_s, dtype=float), load_n, kind,
                                 values, [np.nan] * 4 + [0.0], self.truth_fn, writes)

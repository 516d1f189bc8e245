"""The diagnosis's simulator (model.Simulator) on the C engine (leveler.engine,
host_sim/diagnose/engine.h): a run log replayed open loop or with the firmware
in the loop, from the state the log starts in (start_state.py), with up to two
effects of the catalogue (effects.json). Configs are opened once per file
version (engine.Engine.cached)."""
import collections
import glob
import json
import os
from dataclasses import replace

import numpy as np

from . import edges
from . import run_memo
from . import effects as fx
from .errors import DiagnoseInputError
from .model import CLOSED_LOOP, Simulator, Trace
from .runs import COMMANDS, SIGNALS
from .start_state import DISCHARGE, chatter_track, initial_state

from leveler import engine, paths

# the names --config takes: the checkout's host_sim/configs, else the installed package's copy
CONFIG_DIR = paths.data("host_sim/configs", "configs")
FINE_TICK_S = 0.01      # replay grid for coarse or jittered logs
# The resolved config's sections behind each valve: while it stays shut nothing
# of them reaches the pipe (plant_derivatives: a shut valve's flow is exactly 0,
# and no other term couples them to P1), so they cannot move a replay's P1.
BEHIND_VALVE = {"spring_valve": ("spring_valve", "spring", "platform", "hysteresis"),
                "vent_valve": ("vent_valve",), "acc_valve": ("accumulator",)}
OMEGA_WINDOW_S = 3.0    # the motor speed is fitted to P1 over at most this long


def config_path(name):
    if os.path.sep in name or name.endswith(".ini"):
        return os.path.abspath(name)
    return os.path.join(CONFIG_DIR, name + ".ini")


def request_commands():
    """{manual request column: the actuator it asks for, named as COMMANDS (the trace's
    commands)}, from the C table of schedule columns."""
    return {c: COMMANDS[k] for c, k in engine.schedule_column_outputs().items()}


def effect_arrays(kind, values):
    """A request's kinds and parameters: an id with its list of values, or a list
    of up to fx.MAX_AT_ONCE ids with a list of lists."""
    if np.isscalar(kind):
        kind, values = ([kind], [values]) if kind else ([], [])
    kinds = np.zeros(engine.MAX_MODELS, dtype=np.int32)
    p = np.zeros((engine.MAX_MODELS, engine.MAX_PARAMS))
    for i, (k, v) in enumerate(zip(kind, values)):
        kinds[i] = k
        p[i, :len(v)] = v
    return kinds, p


def nearest_index(rel, grid):
    """For each grid time the index of the nearest sample of rel: a switch seen
    between two samples is placed halfway between them (an edge is only known
    within a sample)."""
    idx = np.clip(np.searchsorted(rel, grid), 0, len(rel) - 1)
    prev = np.clip(idx - 1, 0, len(rel) - 1)
    nearer_prev = np.abs(grid - rel[prev]) <= np.abs(rel[idx] - grid)
    idx = np.where(nearer_prev, prev, idx)
    return idx


def run_tracks(run):
    """The P1 the compressor's and the P2 the discharge's chatter regulate to (chatter_track)."""
    return chatter_track(run), chatter_track(run, DISCHARGE, "p_spring_pa", trim=True)


def fine_grid(run):
    """A coarse log's 10 ms replay grid (CPlant._fine_inputs): times from the start,
    the grid, each tick's nearest sample, the commands on the grid, the load on
    the grid, and each sample's nearest tick."""
    rel = run.t_s - run.t_s[0]
    grid = np.round(np.arange(0.0, rel[-1] + FINE_TICK_S / 2, FINE_TICK_S), 6)
    idx = nearest_index(rel, grid)
    placed = getattr(run, "fine_commands", None)
    if placed and all(len(v) >= len(grid) for v in placed.values()):    # a cut run keeps its start
        cmds = {k: np.asarray(v[:len(grid)]) for k, v in placed.items()}
    else:
        cmds = {k: np.asarray(v)[idx] for k, v in run.commands.items()}
    return rel, grid, idx, cmds, np.asarray(run.load_n)[idx], nearest_index(grid, rel)


def is_fine(t_s, tick=FINE_TICK_S):
    rel = t_s - t_s[0]
    return len(rel) > 1 and np.allclose(np.diff(rel), tick, atol=1e-6)


def floor_above_noise(run):
    """A log slower than the tick whose accumulator valve switches: replayed with its
    switches halfway the rig's own config leaves a median 4.3 times the logs' noise
    (1.25 against 0.29 on 30 effect-free logs), so its switches are placed
    (CPlant.placed); even then 1.1-1.4 times (edges.py; 900 lb rig logs 1.2 times), so a gap
    within a noise gap or so does not say no effect is there."""
    acc = run.commands.get("acc_valve") if getattr(run, "commands", None) else None
    t = getattr(run, "t_s", None)
    return bool(t is not None and not is_fine(np.asarray(t)) and acc is not None
                and np.any(np.diff(np.asarray(acc, dtype=int)) != 0))



class CPlant(Simulator):
    honours_start_shift = True

    def __init__(self, lib_path=None):
        self.lib_path = lib_path
        engine.library(lib_path)      # found and checked now: a missing library fails here
        self._motor_cache = {}
        self._omega_cache = {}
        self._start_cache = collections.OrderedDict()
        self._resolved = collections.OrderedDict()     # a config handle's resolved config (_window_config)

    def handle(self, config, effects_nominal=False, lib=None):
        """The config's open handle; DiagnoseInputError naming the file, line and field."""
        try:
            return engine.Engine.cached(config_path(config), effects_nominal, lib or self.lib_path)
        except (engine.EngineError, DiagnoseInputError) as e:
            raise DiagnoseInputError(str(e)) from None

    def config_effects(self, config):
        """The config's own effects ([effect.NAME] sections, which the C plant runs on
        every run): {name: {parameter: value}}."""
        ids, vals = self.handle(config).effects()
        out = {}
        for i, k in enumerate(ids):
            if k:
                e = fx.BY_ID[int(k)]
                out[e.name] = {q.name: float(vals[i, j]) for j, q in enumerate(e.params)}
        return out

    def configs(self):
        return sorted(os.path.splitext(os.path.basename(p))[0]
                      for p in glob.glob(os.path.join(CONFIG_DIR, "*.ini")))

    def check_config(self, name):
        path = config_path(name)
        if not os.path.isfile(path):
            raise DiagnoseInputError(f"--config: no plant config {name!r} ({path} does not exist; "
                                     f"known: {', '.join(self.configs())})")
        self.handle(name)

    def _call(self, config, t_s, load_n, commands, kind, values, init, track=None, writes=None,
              effects_nominal=False, catalogue=engine.CANDIDATES, lib=None, track2=None):
        """kind: an effect id (0 = none) and values its list, or up to two ids and
        a list of lists (two effects at once). commands None: the firmware in the loop.
        track, track2: the P1 the compressor and the P2 the discharge regulate to
        where finite (chatter_track)."""
        n = len(t_s)
        kinds, p = effect_arrays(kind, values)
        cmd = None
        if commands is not None:
            cmd = np.stack([commands.get(c, np.zeros(n)) for c in COMMANDS], axis=1)
        e = self.handle(config, effects_nominal, lib)
        out, act = e.run(t_s, load_n, cmd, track, writes, init, catalogue, kinds, p, p2_track=track2)
        return Trace(np.ascontiguousarray(t_s, dtype=np.float64), {s: out[:, i].copy() for i, s in enumerate(SIGNALS)},
                     {c: act[:, i].copy() for i, c in enumerate(COMMANDS)})

    def motor_speed(self, config, p1_pa, duty):
        """The motor speed in balance at the start (plant_motor_steady_speed)."""
        key = (config, round(float(p1_pa), 0), round(duty, 3))
        if key not in self._motor_cache:
            self._motor_cache[key] = self.handle(config).motor_speed(p1_pa, duty)
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
        t = run.t_s
        n = int(np.searchsorted(t, t[0] + OMEGA_WINDOW_S))
        load_change = np.flatnonzero(np.abs(np.diff(run.load_n[:n])) > 1.0)
        n = int(load_change[0]) + 1 if load_change.size else n
        p1 = run.signals["p_pipe_pa"][:n]
        if not (comp is not None and np.any(comp[:n]) and np.isfinite(p1).sum() > 10 and n > 10):
            return self.motor_speed(config, init[2], duty) if np.isfinite(init[2]) else 0.0, 0.0
        key = (self._window_config(config, run, n), run.path, hash(run.signals["p_pipe_pa"].tobytes()),
               hash(np.asarray(comp).tobytes()))
        if key in self._omega_cache:
            return self._omega_cache[key]
        grid = np.linspace(0.0, max(self.motor_speed(config, init[2], 1.0), 1.0) * 1.5, 13)
        cmds = {k: np.asarray(v[:n]) for k, v in run.commands.items()}
        cost, shift = [], []
        for w in grid:
            r = self._call(config, t[:n], run.load_n[:n], cmds, 0, [], init + [w],
                           effects_nominal=True).signals["p_pipe_pa"] - p1
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

    def _window_config(self, config, run, n):
        """What of the config the start's replay (start_motor_speed, the nominal plant
        over the run's first n samples) can depend on, as a string: the resolved
        config (exact numbers) without its name and path, and without what lies
        behind a valve the run keeps shut over those samples (BEHIND_VALVE). A
        calibration writes a config per trial; the trials that move only values
        behind a shut valve then share the replay's result, bit for bit."""
        drop = {"config"}
        for valve, sections in BEHIND_VALVE.items():
            c = run.commands.get(valve) if run.commands else None
            if c is not None and not np.any(np.asarray(c[:n])):
                drop.update(sections)
        h = self.handle(config, True)
        hit = self._resolved.get(id(h))
        if hit is None or hit[0] is not h:      # the handle is held: its id is not reused while cached
            hit = self._resolved[id(h)] = (h, h.config_json())
            while len(self._resolved) > self.START_CACHE:
                self._resolved.popitem(last=False)
        return json.dumps({k: v for k, v in hit[1].items() if k not in drop}, sort_keys=True)

    START_CACHE = 256

    def _log_start(self, config, run):
        """initial_state and the motor's start of a run, once per run object (a fit
        asks for them at every evaluation; runs are never changed in place). The
        cache holds the run itself, so its id is not reused while cached."""
        key = (config, id(run))
        hit = self._start_cache.get(key)
        if hit is None or hit[0] is not run:
            init, duty = initial_state(run)
            # on the nominal plant, whether the effects are asked for or in the config
            omega, p1_shift = self.start_motor_speed(config, run, list(init), duty)
            hit = self._start_cache[key] = (run, init, omega, p1_shift)
            while len(self._start_cache) > self.START_CACHE:
                self._start_cache.popitem(last=False)
        return list(hit[1]), hit[2], hit[3]

    def start_state(self, config, run, effect=None, params=None):
        """The 5 initial values a run starts from (engine_request.init), estimated from the log."""
        init, omega, p1_shift = self._log_start(config, run)
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
        if run_memo.of_run(run, "fine", lambda r: is_fine(r.t_s)):
            # the tick's own log: every switch is there, replayed as is
            return self._call(config, run.t_s, run.load_n, run.commands, kind, values, init)
        track, track2 = run_memo.of_run(run, "tracks", run_tracks)
        return self._replay_fine(config, run, kind, values, init, track, track2)

    def _fine_inputs(self, run, track, track2):
        """A coarse log on the 10 ms replay grid: the grid, each tick's nearest sample,
        the commands switched halfway between samples (or run.fine_commands, placed),
        and the chatter tracks at the ticks."""
        rel, grid, idx, cmds = run_memo.of_run(run, "grid", fine_grid)[:4]
        # the nearest sample's (already smoothed) value
        track, track2 = (None if x is None else x[idx] for x in (track, track2))
        return rel, grid, idx, cmds, track, track2

    def _replay_fine(self, config, run, kind, values, init, track=None, track2=None):
        """A coarse or jittered log: replay on the 10 ms grid with each switch halfway
        between the samples that bracket it (or where place_switches put it), read
        back at the log's times; where a command chatters, regulated to its track
        instead (chatter_track)."""
        rel, grid, idx, cmds, track, track2 = self._fine_inputs(run, track, track2)
        load, back = run_memo.of_run(run, "grid", fine_grid)[4:]
        tr = self._call(config, grid, load, cmds, kind, values, init, track, track2=track2)
        return Trace(run.t_s, {k: np.interp(rel, grid, v) for k, v in tr.signals.items()},
                     {k: v[back] for k, v in tr.commands.items()})

    def placed(self, config, run):
        """The run with fine_commands: its logged switches placed within their
        brackets (edges.py) on the config as given, where the accumulator's bursts
        make a switch's timing matter (floor_above_noise). Any other log is returned
        as it is: without the bursts a half-sample moves little air (900 lb rig logs:
        median gap 0.291 halfway, 0.280 placed), and the pipe's volume shows in P1 at
        the same switches (placed there, misset seed 1's pipe +30 % rig log came out
        +24.2 % and its experiment "not explained")."""
        if not (run.has_commands and len(run.t_s) > 2 and floor_above_noise(run)):
            return run
        run = replace(run, fine_commands=None)
        rel, grid, idx, cmds, tk, tk2 = self._fine_inputs(run, *run_tracks(run))
        load, init = np.asarray(run.load_n)[idx], self.start_state(config, run)

        def replay(c, end):
            cut = lambda x: None if x is None else x[:end]
            return self._call(config, grid[:end], load[:end], c, 0, [], init, cut(tk), track2=cut(tk2)).signals

        def skip(k, g):     # the discharge regulated to its track there (the compressor is never placed)
            return k in DISCHARGE and tk2 is not None and bool(np.isfinite(tk2[g]))
        groups = edges.switch_groups(rel, run.commands, grid, skip)
        return replace(run, fine_commands=edges.place_switches(replay, rel, run.signals, cmds, grid, groups))

    def _closed_loop(self, config, t_s, load_n, kind, values, init, writes=None, **where):
        """The firmware ticks every 10 ms: simulate on that grid from the log's first
        time, holding the logged load, then read the trace at the log's own times.
        writes: a schedule's register writes [(t_s from the start, {register: value})],
        made through the firmware's register map during the run. where: the effect
        table (catalogue) and the engine's build (lib) of a truth (generate)."""
        tick = engine.tick_s()
        rel = t_s - t_s[0]
        if len(rel) > 1 and np.allclose(np.diff(rel), tick, atol=1e-6) and abs(rel[0]) < 1e-9:
            return self._call(config, np.round(rel, 2), load_n, None, kind, values, init, writes=writes, **where)
        grid = np.arange(0.0, rel[-1] + tick / 2, tick)
        idx = np.clip(np.searchsorted(rel, grid, side="right") - 1, 0, len(rel) - 1)
        tr = self._call(config, grid, np.asarray(load_n)[idx], None, kind, values, init, writes=writes, **where)
        back = np.clip(np.searchsorted(grid, rel, side="right") - 1, 0, len(grid) - 1)
        return Trace(t_s, {k: np.interp(rel, grid, v) for k, v in tr.signals.items()},
                     {k: v[back] for k, v in tr.commands.items()})

    def generate(self, config, t_s, load_n, truth_effect, truth_params, seed=0, writes=None,
                 catalogue=engine.TRUTH):
        """Closed loop with a truth of the blind test (the engine's truth build,
        libleveler_truth.so; catalogue TRUTH: the first family, ids as the
        candidates'; TRUTH2 with truth_effect an int: a form of the second):
        truth_params the truth's list of values (for a pair "a+b", a list of the
        two lists). None: the nominal plant, on the product's engine. The rig
        starts at rest: platform still, motor stopped. writes: a schedule's
        register writes (mode, manual requests) as in _closed_loop."""
        if isinstance(truth_effect, int):
            kind, values = ([truth_effect], [list(truth_params)]) if truth_effect else ([], [])
        else:
            names = fx.parts(truth_effect)
            kind = [fx.get(e).effect_id for e in names]
            values = list(truth_params or []) if len(names) > 1 else [list(truth_params or [])] * len(names)
        where = {"catalogue": catalogue, "lib": engine.find_truth_library()} if kind else {}
        return self._closed_loop(config, np.asarray(t_s, dtype=float), load_n, kind, values,
                                 [np.nan] * 4 + [0.0], writes, **where)

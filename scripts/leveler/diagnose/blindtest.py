"""leveler-blindtest: does the diagnosis name the effect that is really there?

For each case (seven effects and `none`) and seed: the C plant with the
effect's TRUTH variant (a different functional form from the candidate the
diagnosis fits: host_sim/blindtest/truth.c, catalogued in truth.json, built
into libleveler_truth.so, not part of the product) at a random strength
within its physical range runs closed loop with the firmware, on three
different load schedules (two for calibration, one held out). Each case draws
a system (900 lb, 1000 lb, or 900 lb with the diaphragm accumulator under
algorithm 2) and a log kind: a 100 Hz 12-bit log, or a rig-rate log (20-50 Hz,
jittered time stamps, 10-11 bit, more noise); `--system 1000lb-accumulator` (the 1000 lb
rig with its diaphragm accumulator under algorithm 2) only when asked for, outside the
rotation. The firmware reads the sensors
with one count of noise, as on a rig (algorithm 2 then chatters at the charge
limit). The label is sealed in a file the diagnosis never sees; the diagnosis
runs as a separate process on the logs alone. When it reports look-alikes
(or says `unsure` of a set of two effects or more, with an experiment), the
experiment it proposes is run on the same truth and the look-alikes are
scored on it: the case counts as right only when that names the truth.
Then: confusion matrix, hit rate, held-out shrink of the correctly named
cases, false effects in `none` cases.

Pair cases (--pairs per seed): two truth effects at once, each at a random
strength within its range, the pair rotating over all 21 so that no two cases
of a run repeat one. Scored "both among the top two": the combination the
diagnosis kept, else its ranked combination (the leader and the effect that
best explains what the leader leaves).

Other truth families (--family; host_sim/blindtest/README.md): `offform`, forms of the
seven effects written from the physics alone, apart from the candidates (truth2.c,
truth2.json; measure on them, never tune); `unknown`, effects outside the catalogue
(right: no catalogued effect named); `misset`, rigs that differ from thesis-900lb in one
nominal parameter and have no effect (right: no effect named and, when the diagnosis
reports a `calibration`, the parameter among those it moved); `combo`, a first-family
(present) truth effect on such a mis-set rig (right: the effect named and the parameter
among those moved; a tuning family like `present`); `all`. Each family is
reported with its confusion matrix, hit rate, median held-out shrink when right, false
effects and a line per form, and the stated `confidence` levels in a reliability table.

Targets (docs/diagnosis.md): >= 95 % named right, median shrink >= 85 % when
right, no effect named in a `none` case; pairs: both among the top two in
>= 80 % (8 of 10).
"""
import itertools
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

import leveler
from leveler import cli as leveler_cli
from leveler import config as leveler_config
from leveler import engine, paths, runlog, thesis

from . import blindtest_run
from . import design
from . import effects as fx
from . import runs
from .cplant import CONFIG_DIR
from leveler.engine import read_schedule, tick_grid
from .model import make_simulator

LB = thesis.N_PER_LBF
CONFIG = "thesis-900lb"
CASES = fx.NAMES + ["none"]
PAIRS = [fx.combine(p) for p in itertools.combinations(fx.NAMES, 2)]
PAIR_STRIDE = 8     # coprime with the 21 pairs: consecutive pair cases visit them all
# system: (config, base lb, calibration steps lb, held-out step lb); loaded states
# stay in one hysteresis band of the thesis (1050..1150 lb at 900, >= 1150 lb at 1000)
SYSTEMS = {
    "900lb": ("thesis-900lb", 900.0, (240.0, 150.0), 200.0),
    "1000lb": ("thesis-1000lb", 1000.0, (240.0, 180.0), 210.0),
    "accumulator": ("thesis-900lb-diaphragm", 900.0, (240.0, 150.0), 200.0),
}
# systems only run when asked for (--system): outside the rotation, so the seeds' cases stay the same
EXTRA_SYSTEMS = {
    "1000lb-accumulator": ("thesis-1000lb-diaphragm", 1000.0, (240.0, 180.0), 210.0),
}
ALL_SYSTEMS = {**SYSTEMS, **EXTRA_SYSTEMS}
ACCUMULATOR_SYSTEMS = {"accumulator", "1000lb-accumulator"}    # those whose logs hold P3
FIRMWARE_NOISE_COUNTS = 1.0
# log kinds: (name, rate range Hz, jitter fraction of a period, bits, height noise m, pressure noise Pa)
LOG_KINDS = {
    "100Hz": (100.0, 100.0, 0.0, 12, 0.08e-3, 300.0),
    "rig": (20.0, 50.0, 0.2, (10, 11), 0.15e-3, 600.0),
}
HEIGHT_SPAN_M = 0.25
PRESSURE_SPAN_PA = 1.38e6

TRUTH_CATALOGUE = paths.data("host_sim/blindtest/truth.json", "blindtest/truth.json")


def _truth_catalogue():
    with open(TRUTH_CATALOGUE) as fh:
        return {e["name"]: e for e in json.load(fh)["effects"]}


TRUTH = _truth_catalogue()

# The second truth family (host_sim/blindtest/truth2.json, README.md there): forms written
# from the physics alone, apart from the candidates, never tuned against. "offform": forms
# of the catalogue's effects; "unknown": effects outside the catalogue.
TRUTH2_CATALOGUE = os.path.join(os.path.dirname(TRUTH_CATALOGUE), "truth2.json")
with open(TRUTH2_CATALOGUE) as _fh:
    FORMS = {e["name"]: e for e in json.load(_fh)["effects"]}
# "misset": rigs that differ from the system's config in one nominal parameter only, no
# unmodelled effect: (name, the parameter as the report names it, [(section, SI key)], factor
# or ("=", value)). The log is made with the changed config, diagnosed with the system's own.
MISSET = [
    ("capacity-15%", "compressor_capacity", [("compressor", "capacity_m3_per_rad")], 0.85),
    ("damping*1.5", "damping", [("platform", "damping_up_n_s_per_m"), ("platform", "damping_down_n_s_per_m")], 1.5),
    ("spring_valve_cd-25%", "spring_valve_cd", [("spring_valve", "cd_into_spring"),
                                                ("spring_valve", "cd_out_of_spring")], 0.75),
    ("spring_volume+15%", "spring_volume", [("spring", "volume_m3")], 1.15),
    ("pipe_volume+30%", "pipe_volume", [("pipe", "volume_m3")], 1.3),
    ("vent_cd-25%", "vent_valve_cd", [("vent_valve", "cd")], 0.75),
    ("polytropic_n=1.0", "polytropic_exponent", [("ambient", "polytropic_exponent")], ("=", 1.0)),
    ("polytropic_n=1.4", "polytropic_exponent", [("ambient", "polytropic_exponent")], ("=", 1.4)),
]
# "combo": a first-family truth effect on a mis-set rig, each effect with one MISSET
# change (their calibration and the effect must both be found; the effect's truth is the
# present family's, so this family may be tuned on). A line delay with a larger pipe is
# the hardest: the candidate and the calibration stand in for each other.
COMBO = [("thermal", "capacity-15%"), ("area", "damping*1.5"), ("friction", "spring_valve_cd-25%"),
         ("valve_dynamics", "spring_volume+15%"), ("line_delay", "pipe_volume+30%"), ("leak", "vent_cd-25%"),
         ("sensor_lag", "polytropic_n=1.0")]
FAMILIES = ("present", "offform", "unknown", "misset", "combo")
APART = ("offform", "unknown", "misset")    # written apart from the candidates: measured on, never tuned


def family_specs(family):
    """The cases of a family other than `present`: dicts with family, form, truth (the
    effect the answer should be: a catalogue effect, "unknown" or "none") and, for a
    form, its truth2 id; for a misset rig the parameter and the config change; and
    its slot (the seed's stream of random numbers and its system and log kind)."""
    if family in ("offform", "unknown"):
        specs = [{"family": family, "form": n, "truth": e["effect"], "form_id": e["id"]}
                 for n, e in FORMS.items() if e["family"] == family]
    else:
        specs = [{"family": "misset", "form": n, "truth": "none", "param": par, "keys": keys, "change": ch}
                 for n, par, keys, ch in MISSET]
    if family == "combo":
        by_name = {m["form"]: m for m in specs}
        specs = [dict(by_name[m], family="combo", form=f"{e}@{m}", truth=e, form_id=None) for e, m in COMBO]
    return [dict(sp, slot=100 * FAMILIES.index(family) + i) for i, sp in enumerate(specs)]


def form_params(form, rng):
    """A form's random strength within its "draw" range (truth2.json)."""
    return [float(rng.uniform(*p["draw"])) for p in FORMS[form]["params"]]


def truth_params(effect, rng):
    """Random strength within physical ranges (truth.json "draw"), in the truth variant's parameter order."""
    if effect not in TRUTH:
        return []
    return [float(rng.uniform(*p["draw"])) for p in TRUTH[effect]["params"]]


WALK_S = 600.0      # --shape walk: a rig in service, 10 minutes
WALK_STEPS = 15     # load changes of random size and sign per walk


def walk(rng, base_lb, top_lb, end_s=WALK_S, steps=WALK_STEPS):
    """A load walk as a rig in service logs it: `steps` changes at random times
    (at least 20 s apart, the first after 5 s), each to a random load between the
    base and the top, at least 40 lb from the last (up or down)."""
    slack = rng.dirichlet(np.ones(steps + 1)) * (end_s - 30.0 - 20.0 * steps)
    times = 5.0 + np.cumsum(20.0 + slack[:steps]) - 20.0     # the last at most end_s - 45 s
    load, out = base_lb, [(0.0, base_lb * LB)]
    for t in times:
        nxt = load
        while abs(nxt - load) < 40.0:
            nxt = float(rng.uniform(base_lb, top_lb))
        load = nxt
        out.append((float(round(t, 2)), load * LB))
    return out


def schedules(rng, system, shape="step"):
    """Two calibration schedules and one held-out one, all different. The
    held-out step lies between the calibration steps: it tests the fitted
    model on a new schedule, not on heights no calibration run reached.
    shape "walk": three 10-minute walks of 15 load changes each (walk), between
    the base and the largest calibration step."""
    _, base_lb, (c1, c2), h = ALL_SYSTEMS[system]
    if shape == "walk":
        return [(name, walk(rng, base_lb, base_lb + max(c1, c2)), WALK_S) for name in ("cal1", "cal2", "hold")]
    j = lambda: rng.uniform(-1.0, 1.0)
    base = base_lb * LB
    return [
        ("cal1", [(0.0, base), (5.0 + j(), base + c1 * LB), (35.0 + j(), base)], 55.0),
        ("cal2", [(0.0, base), (4.0 + j(), base + c2 * LB), (31.0 + j(), base)], 50.0),
        ("hold", [(0.0, base), (6.0 + j(), base + h * LB), (33.0 + j(), base)], 52.0),
    ]


def case_kind(seed, slot):
    """System and log kind of a case (its slot: CASES' index, then the pair cases
    after them): every seed covers all of them, rotating."""
    k = seed * 7 + slot
    return list(SYSTEMS)[k % len(SYSTEMS)], list(LOG_KINDS)[(k // len(SYSTEMS)) % len(LOG_KINDS)]


def pair_case(seed, j, per_seed):
    """The j-th pair case of a seed."""
    return PAIRS[((seed - 1) * per_seed + j) * PAIR_STRIDE % len(PAIRS)]


def rig_config(folder, system, seed, misset=None, algorithm=None):
    """The system's config with a count of sensor noise the firmware reads, on a rig run
    as the thesis's was: no chatter fault stops algorithm 2's compressor chattering at the
    charge limit (a rig with the product default would go safe and show no effect).
    misset: a MISSET case (family_specs): its one nominal parameter changed, the rest the
    system's (resolved by the C loader). algorithm: the rig's controller (default the config's)."""
    path = os.path.join(folder, "rig.ini")
    base = os.path.join(CONFIG_DIR, ALL_SYSTEMS[system][0] + ".ini")
    sections = {"sensors": [f"noise_counts = {FIRMWARE_NOISE_COUNTS}", f"noise_seed = {seed}"],
                "controller": ["chatter_max_per_min = 0"] + ([f"algorithm = {algorithm}"] if algorithm else [])}
    if misset:
        resolved = leveler_config.resolved(base)
        for sec, key in misset["keys"]:
            ch = misset["change"]
            value = ch[1] if isinstance(ch, tuple) else resolved[sec][key] * ch
            sections.setdefault(sec, []).append(f"{key} = {value!r}")
    with open(path, "w") as fh:
        fh.write(f"[config]\ninclude = {base}\nname = blindtest-rig\n")
        for sec, lines in sections.items():
            fh.write(f"\n[{sec}]\n" + "".join(f"{x}\n" for x in lines))
    return path


def log_times(rng, kind, end):
    """Sample times of a log: 100 Hz on the tick grid, or a jittered rig rate."""
    lo, hi, jit = LOG_KINDS[kind][:3]
    if jit == 0.0:
        return tick_grid(end)
    dt = 1.0 / rng.uniform(lo, hi)
    t = np.arange(0.0, end, dt) + rng.uniform(-jit, jit, int(np.ceil(end / dt))) * dt
    t[0] = 0.0
    return np.unique(np.round(t, 4))


def quantise(v, span, bits):
    lsb = span / (2 ** bits)
    return np.round(v / lsb) * lsb


def generate_form(sim, rig, t, load, form_id, params, writes=None):
    """Closed loop with a form of the second family (the engine's table TRUTH2 in
    libleveler_truth.so) from rest, as CPlant.generate runs the first family's."""
    return sim.generate(rig, np.round(np.asarray(t, dtype=float), 2), load, int(form_id), params, 0, writes,
                        catalogue=engine.TRUTH2)


def write_truth_log(sim, path, rig, system, steps, end, effect, params, kind, rng, writes=None, form_id=None):
    """Run the truth closed loop on the 10 ms tick and write the log the rig would
    (writes: a schedule's mode / manual rows, made through the firmware's register map;
    form_id: a form of the second family in place of the effect's first-family truth)."""
    t = tick_grid(end)
    load = design.schedule_loads(t, steps)
    if form_id is not None:
        tr = generate_form(sim, rig, t, load, form_id, params, writes)
    else:
        tr = sim.generate(rig, t, load, effect, params, 0, **({"writes": writes} if writes else {}))
    ts = log_times(rng, kind, end)
    idx = np.clip(np.searchsorted(t, ts + 1e-9, side="right") - 1, 0, len(t) - 1)  # in force at ts
    bits = LOG_KINDS[kind][3]
    bits = int(rng.integers(bits[0], bits[1] + 1)) if isinstance(bits, tuple) else bits
    nh, npr = LOG_KINDS[kind][4:]
    sig = {"height_m": quantise(np.interp(ts, t, tr.signals["height_m"]) + rng.normal(0.0, nh, len(ts)),
                                HEIGHT_SPAN_M, bits)}
    for s in runlog.PRESSURES:
        v = np.interp(ts, t, tr.signals[s]) + rng.normal(0.0, npr, len(ts))
        sig[s] = quantise(v, PRESSURE_SPAN_PA, bits)
    if system not in ACCUMULATOR_SYSTEMS:
        sig["p_acc_pa"] = np.full(len(ts), np.nan)
    cmds = {k: v[idx] for k, v in tr.commands.items()}
    runs.write_run(path, ts, sig, load[idx], cmds, ALL_SYSTEMS[system][0], "rig")


def generate_case(sim, effect, seed, folder, system="900lb", kind="100Hz", slot=None, shape="step",
                  algorithm=None):
    """Writes cal1.csv, cal2.csv, hold.csv; returns the truth parameters (for a
    pair "a+b" the two lists)."""
    rng = np.random.default_rng(seed * 1000 + (CASES.index(effect) if slot is None else slot))
    names = fx.parts(effect)
    params = [truth_params(e, rng) for e in names] if len(names) > 1 else truth_params(effect, rng)
    rig = rig_config(os.path.dirname(os.path.abspath(folder)), system, seed, algorithm=algorithm)
    for name, steps, end in schedules(rng, system, shape):
        write_truth_log(sim, os.path.join(folder, f"{name}.csv"), rig, system, steps, end, effect, params,
                        kind, rng)
    return params


def logged_seconds(folder, names=("cal1", "cal2", "hold")):
    """The logs' total span, s: what one diagnosis simulates once per model."""
    return float(sum(np.ptp(runs.load_run(os.path.join(folder, f"{n}.csv")).t_s) for n in names))


def diagnose_blind(folder, out, config, extra, runs_=("cal1", "cal2"), holdout=("hold",)):
    """The diagnosis as its own process, on the logs only."""
    cmd = [sys.executable, "-m", "leveler.diagnose", "--config", config]
    for r in runs_:
        cmd += ["--run", os.path.join(folder, f"{r}.csv")]
    for r in holdout:
        cmd += ["--holdout", os.path.join(folder, f"{r}.csv")]
    cmd += ["--out", out, "--quiet"] + list(extra)
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode != 0:
        raise RuntimeError(f"diagnosis failed ({p.returncode}): {p.stderr.strip()}")
    with open(os.path.join(out, "diagnosis.json")) as fh:
        return json.load(fh)


def lookalike_set(d):
    """What a diagnosis says it cannot tell apart: its look-alike effects, an effect
    and the calibration that explain the held-out runs alike (its `rival`), no
    effect and the one the logs hint at (confidence.hinted: the set [effect, "none"]
    with an experiment), or the effects of any other `unsure` set that comes with an
    experiment (two at least): a user told "unsure" runs the experiment proposed."""
    rival = (d.get("calibration") or {}).get("rival")
    conf = d.get("confidence") or {}
    cset = conf.get("set", []) if d.get("experiment") else []
    hint = cset if "none" in cset else []
    unsure = [x for x in cset if x in fx.NAMES] if conf.get("level") == "unsure" else []
    return (d.get("cannot_tell_apart") or ([rival["effect"], "calibration"] if rival else hint)
            or (unsure if len(unsure) >= 2 else []))


def run_experiment(sim, folder, d, case, params, system, kind, seed, extra, spec=None):
    """Look-alikes: run the proposed experiment on the same truth and score the
    look-alikes, fitted on the calibration runs as before, on it: the experiment
    was designed from their predictions, so it is the held-out run that decides.
    It joins the first held-out run, not replaces it: an experiment that does not
    exercise what the calibration found (a pulse train of the spring valve against
    a vent's Cd) would have the calibration dropped, and the effects judged on the
    config as given. Returns the new diagnosis. spec: a case of another family."""
    logs = os.path.join(folder, "logs")
    steps, end = read_schedule(os.path.join(folder, "diagnosis", "experiment.csv"))
    slot = CASES.index(case) if spec is None else spec["slot"]
    rng = np.random.default_rng(seed * 1000 + slot + 500)   # single cases only
    rig = os.path.join(folder, "rig.ini")
    write_truth_log(sim, os.path.join(logs, "experiment.csv"), rig, system, steps, end, case, params, kind, rng,
                    design.schedule_writes(steps), form_id=None if spec is None else spec["form_id"])
    group = ",".join(x for x in lookalike_set(d) if x in fx.NAMES)     # the set's effects, not none/calibration
    return diagnose_blind(logs, os.path.join(folder, "diagnosis-experiment"), ALL_SYSTEMS[system][0],
                          list(extra) + ["--effects", group], holdout=("hold", "experiment"))


def run_case(sim, top, seed, case, index, extra, force=(None, None, "step", None), slot=None):
    """One case: a single effect (slot None: its place in CASES) or a pair (slot given).
    force: (system, log kind, schedule shape, algorithm), None = the rotation's / config's."""
    system, kind = case_kind(seed, CASES.index(case) if slot is None else slot)
    system, kind = force[0] or system, force[1] or kind
    folder = os.path.join(top, f"seed{seed}-{index:02d}")
    logs = os.path.join(folder, "logs")
    os.makedirs(logs, exist_ok=True)
    params = generate_case(sim, case, seed, logs, system, kind, slot, *force[2:])
    # the sealed label: beside the logs, never passed to the diagnosis
    with open(os.path.join(folder, "label.sealed.json"), "w") as fh:
        json.dump({"effect": case, "truth_params": params, "seed": seed, "system": system, "log": kind}, fh)
    t0 = time.perf_counter()
    d = diagnose_blind(logs, os.path.join(folder, "diagnosis"), ALL_SYSTEMS[system][0], extra)
    r = {"seed": seed, "truth": case, "system": system, "log": kind, "named": d["effect"],
         "shrink_pct": d["shrink_pct"], "margin_pct": d["margin_pct"], "seconds": time.perf_counter() - t0,
         "logged_s": logged_seconds(logs),
         "lookalikes": lookalike_set(d),
         "ranking": [(x["effect"], round(x["shrink_pct"], 1)) for x in d["ranking"]],
         "effects": d.get("effects", []), "confidence": confidence_level(d),
         "calibrated": _calibration_names(d.get("calibration")),
         "pairs": [(x["effect"], round(x["shrink_pct"], 1), x["kept"]) for x in d.get("pairs", [])]}
    r["verdict"] = d["effect"]
    r["ranked_combination"] = d.get("ranked_combination") or [x[0] for x in r["ranking"][:2]]
    if slot is not None:        # a pair: both among the top two (the kept pair, else the ranked combination)
        r["top_two"] = r["effects"] if len(r["effects"]) == 2 else r["ranked_combination"]
        r["both_top_two"] = set(fx.parts(case)) == set(r["top_two"])
        return r
    if r["lookalikes"]:
        r["after_experiment"] = (run_experiment(sim, folder, d, case, params, system, kind, seed, extra)["effect"]
                                 if case in r["lookalikes"] else "truth not among them")
        r["verdict"] = r["after_experiment"]
    return r


def _calibration_names(cal):
    """The nominal parameters a diagnosis's `calibration` field says moved (h21d's
    calibration stage; read loosely: a list of entries or a dict by name, an entry
    counting as moved unless it says moved/identifiable false)."""
    if not cal:
        return []
    if isinstance(cal, dict) and isinstance(cal.get("moved"), list):
        # with a rival effect the calibration's values are its look-alike: they moved
        moved = cal["moved"] + list((cal.get("rival") or {}).get("moved", []))
        return list(dict.fromkeys(str(x.get("name", x) if isinstance(x, dict) else x) for x in moved))
    items = cal.get("parameters", cal) if isinstance(cal, dict) else cal
    if isinstance(items, dict):
        items = [dict(v, name=k) if isinstance(v, dict) else {"name": k, "value": v} for k, v in items.items()]
    out = []
    for x in items if isinstance(items, list) else []:
        if isinstance(x, dict) and x.get("moved", True) is not False:
            out.append(str(x.get("name") or x.get("key") or x.get("parameter") or x))
    return out


def confidence_level(d):
    """The diagnosis's stated confidence as a level (a string), or None without one."""
    c = d.get("confidence")
    if c is None:
        return None
    if isinstance(c, dict):
        c = c.get("level", c.get("probability"))
    return str(c)


def param_named(names, param):
    """Whether the misset parameter is among the calibrated ones (its words in a name)."""
    words = param.split("_")
    return any(all(w in n.lower() for w in words) for n in names)


def form_logs(sim, folder, seed, spec, force=(None, None, "step", None)):
    """A case of another family: its rig (folder/rig.ini) and its logs cal1, cal2
    and hold in folder/logs. Returns (spec with its form_id, system, log kind, truth
    parameters, effect)."""
    combo = spec["family"] == "combo"
    spec = dict(spec, form_id=None if combo else spec.get("form_id", 0))
    system, kind = case_kind(seed, spec["slot"])
    if spec["family"] in ("misset", "combo"):
        system = "900lb"    # rigs that differ from thesis-900lb in one parameter (issue 21)
    system, kind = force[0] or system, force[1] or kind
    logs = os.path.join(folder, "logs")
    os.makedirs(logs, exist_ok=True)
    rng = np.random.default_rng(seed * 1000 + spec["slot"])
    params = truth_params(spec["truth"], rng) if combo else form_params(spec["form"], rng) if spec["form_id"] else []
    rig = rig_config(folder, system, seed, spec if spec["family"] in ("misset", "combo") else None, force[3])
    effect = spec["truth"] if combo else "none"
    for name, steps, end in schedules(rng, system, force[2]):
        write_truth_log(sim, os.path.join(logs, f"{name}.csv"), rig, system, steps, end, effect, params, kind,
                        rng, form_id=spec["form_id"])
    return spec, system, kind, params, effect


def run_form_case(sim, top, seed, spec, index, extra, force=(None, None, "step", None)):
    """One case of another family (family_specs): a form of the second truth family,
    a mis-set rig with no effect, or one with a first-family effect (combo)."""
    folder = os.path.join(top, f"{spec['family']}-seed{seed}-{index:02d}")
    logs = os.path.join(folder, "logs")
    spec, system, kind, params, effect = form_logs(sim, folder, seed, spec, force)
    with open(os.path.join(folder, "label.sealed.json"), "w") as fh:
        json.dump({k: v for k, v in spec.items()} | {"truth_params": params, "seed": seed, "system": system,
                                                      "log": kind}, fh)
    t0 = time.perf_counter()
    d = diagnose_blind(logs, os.path.join(folder, "diagnosis"), ALL_SYSTEMS[system][0], extra)
    cal = _calibration_names(d.get("calibration"))
    r = {"family": spec["family"], "form": spec["form"], "seed": seed, "truth": spec["truth"], "system": system,
         "log": kind, "named": d["effect"], "verdict": d["effect"], "shrink_pct": d["shrink_pct"],
         "margin_pct": d.get("margin_pct"), "seconds": time.perf_counter() - t0, "truth_params": params,
         "logged_s": logged_seconds(logs),
         "lookalikes": lookalike_set(d), "effects": d.get("effects", []),
         "ranking": [(x["effect"], round(x["shrink_pct"], 1)) for x in d["ranking"]],
         "calibration": d.get("calibration"), "calibrated": cal, "confidence": confidence_level(d),
         "unexplained": d.get("unexplained", d.get("not_explained"))}
    if spec["family"] in ("misset", "combo"):
        r["param"] = spec["param"]
        r["param_named"] = param_named(cal, spec["param"])
    # a mis-set rig's truth among the look-alikes is the calibration, or no effect
    truth_in = [spec["truth"]] if spec["truth"] in fx.NAMES else (["calibration", "none"] if spec["family"] ==
                                                                   "misset" else [])
    if r["lookalikes"] and truth_in:
        r["after_experiment"] = "truth not among them"
        if set(truth_in) & set(r["lookalikes"]):
            d2 = run_experiment(sim, folder, d, effect, params, system, kind, seed, extra, spec)
            r["after_experiment"] = d2["effect"]
            if "param" in r:    # the answer is the one after the experiment: its calibration too
                r["param_named"] = param_named(_calibration_names(d2.get("calibration")), spec["param"])
        r["verdict"] = r["after_experiment"]
    r["right"] = case_right(r)
    return r


def case_right(r):
    """offform: the form's effect named; unknown: no catalogued effect named (none, or
    the tool's own "not explained"); misset: no effect named (and, when the diagnosis
    calibrates, the parameter named); combo: the effect and the parameter named."""
    if r["family"] == "unknown":
        return r["verdict"] not in fx.NAMES and not any(e in fx.NAMES for e in r["effects"])
    if r["family"] == "misset":
        return r["verdict"] == "none" and (r["calibration"] is None or r["param_named"])
    if r["family"] == "combo":
        return r["verdict"] == r["truth"] and r["param_named"]
    return r["verdict"] == r["truth"]


COLUMN = {"truth not among them": "la-miss"}   # look-alikes reported, the truth not among them


def family_report(results):
    """Lines of a family's report: confusion matrix, hit rate, median shrink when right,
    false effects, per form; for misset whether an effect / the parameter was named."""
    if not results:
        return []
    fam = results[0]["family"]
    truths = list(dict.fromkeys(r["truth"] for r in results))
    named = CASES + sorted({r["verdict"] for r in results} - set(CASES))
    lines = [f"== family {fam}: {sum(r['right'] for r in results)}/{len(results)} right "
             f"({100.0 * sum(r['right'] for r in results) / len(results):.0f}%)",
             "truth \\ named  " + " ".join(f"{COLUMN.get(c, c)[:7]:>7}" for c in named)]
    for t in truths:
        lines.append(f"{t:<15}" + " ".join(f"{sum(1 for r in results if r['truth'] == t and r['verdict'] == c):>7}"
                                           for c in named))
    right_sh = [r["shrink_pct"] for r in results if r["right"] and r["truth"] not in ("none", "unknown")]
    if right_sh:
        lines.append(f"median held-out shrink when right: {np.median(right_sh):.1f}%")
    false_eff = sum(1 for r in results if r["truth"] in ("none", "unknown") and r["verdict"] in fx.NAMES)
    second = sum(1 for r in results if len(r["effects"]) > 1)
    lines.append(f"catalogued effect named where there is none of them: {false_eff}; a second effect kept: {second}")
    forms = list(dict.fromkeys(r["form"] for r in results))
    w = max([22] + [len(f) + 1 for f in forms])     # a combo form names its effect and its value
    lines.append(f"{'form':<{w}}{'truth':<15}{'right':>6} {'median shrink':>14}  named")
    for form in forms:
        rs = [r for r in results if r["form"] == form]
        sh = [r["shrink_pct"] for r in rs if r["right"]]
        extra = ""
        if fam in ("misset", "combo"):
            extra = "  param named: " + ",".join("?" if r["calibration"] is None else
                                                 ("yes" if r["param_named"] else "no") for r in rs)
        lines.append(f"{form:<{w}}{rs[0]['truth']:<15}{sum(r['right'] for r in rs):>3}/{len(rs):<2} "
                     f"{(f'{np.median(sh):.1f}%' if sh else '-'):>14}  {', '.join(_named(r) for r in rs)}{extra}")
    return lines


def _named(r):
    """What a case's diagnosis named: its effect, a kept second, look-alikes and the verdict after them."""
    out = r["named"] + ("+" + r["effects"][1] if len(r["effects"]) > 1 else "")
    if r["lookalikes"]:
        out += f" [look-alikes {'/'.join(r['lookalikes'])} -> {r['verdict']}]"
    return out


def print_report(path):
    """The reports of a saved --json of the other families, again (--report)."""
    with open(path) as fh:
        results = json.load(fh)["results"]
    for fam in FAMILIES:
        rs = [r for r in results if r.get("family") == fam]
        if rs:
            print("\n".join(family_report(rs)) + "\n")
    print("\n".join(reliability(results)))


def write_confidence(path, results, on):
    """Each stated level's right / cases over these results (the second truth family's),
    for the diagnosis to state with its verdict (confidence.py)."""
    levels = {}
    for r in results:
        if r.get("confidence") is not None:
            e = levels.setdefault(r["confidence"], {"right": 0, "cases": 0, "on": on})
            e["cases"] += 1
            e["right"] += bool(r["right"])
    with open(path, "w") as fh:
        json.dump(levels, fh, indent=1, sort_keys=True)
        fh.write("\n")


def reliability(results):
    """For each stated confidence level: right of how many (cases with a level only)."""
    levels = {}
    for r in results:
        if r.get("confidence") is not None:
            n, k = levels.get(r["confidence"], (0, 0))
            levels[r["confidence"]] = (n + 1, k + bool(r["right"]))
    if not levels:
        return ["reliability: the diagnosis states no confidence (no `confidence` field)"]
    return ["reliability (confidence level: right / cases)"] + [
        f"  {lvl:<12} {k}/{n} ({100.0 * k / n:.0f}%)" for lvl, (n, k) in sorted(levels.items())]


def confusion(results, key="verdict"):
    lines = ["truth \\ named  " + " ".join(f"{c[:7]:>7}" for c in CASES)]
    for t in CASES:
        row = [sum(1 for r in results if r["truth"] == t and r[key] == c) for c in CASES]
        lines.append(f"{t:<15}" + " ".join(f"{v:>7}" for v in row))
    return "\n".join(lines)


def pair_summary(results):
    """Pair cases: both among the top two; both named (a kept pair); the leader one of the two."""
    n = len(results)
    both = sum(1 for r in results if r["both_top_two"])
    kept = sum(1 for r in results if len(r["effects"]) == 2 and set(r["effects"]) == set(fx.parts(r["truth"])))
    lead = sum(1 for r in results if r["named"] in fx.parts(r["truth"]))
    return {"pair_cases": n, "pairs_both_top_two": both, "pairs_both_kept": kept, "pairs_leader_right": lead,
            "pairs_hit_pct": 100.0 * both / max(n, 1)}


def summary(results):
    """The figures of the targets, overall and per system and log kind."""
    right = [r for r in results if r["verdict"] == r["truth"]]
    eff_right = [r["shrink_pct"] for r in right if r["truth"] != "none"]
    none_cases = [r for r in results if r["truth"] == "none"]
    out = {"hit_pct": 100.0 * len(right) / max(len(results), 1), "right": len(right), "cases": len(results),
           "median_shrink_pct": float(np.median(eff_right)) if eff_right else float("nan"),
           "false_in_none": sum(1 for r in none_cases if r["verdict"] != "none"), "none_cases": len(none_cases),
           "lookalike_cases": sum(1 for r in results if r["lookalikes"]),
           # a second effect kept where there is one effect (or none)
           "false_second": sum(1 for r in results if len(r.get("effects", [])) > 1),
           "median_seconds": float(np.median([r["seconds"] for r in results])) if results else float("nan"),
           # diagnosis time per second of log: a 10-minute walk must cost no more per second than the step test
           "median_s_per_logged_s": float(np.median([r["seconds"] / r["logged_s"] for r in results
                                                     if r.get("logged_s")])) if results else float("nan")}
    for key in ("system", "log"):
        out[f"by_{key}"] = {v: f"{sum(1 for r in right if r[key] == v)}/{sum(1 for r in results if r[key] == v)}"
                            for v in sorted({r[key] for r in results})}
    return out


def print_case(r, pair=False):
    """One line per case of the present family, as it finishes."""
    if pair:
        print(f"{'ok ' if r['both_top_two'] else 'MISS'} seed {r['seed']} {r['system']:<11} {r['log']:<5} "
              f"truth {r['truth']:<26} named {' + '.join(r['effects']) or 'none':<26} top two {r['top_two']} "
              f"held-out shrink {r['shrink_pct']:6.1f}%  ({r['seconds']:.0f} s)  top: {r['ranking'][:3]}  "
              f"pairs: {r['pairs']}", flush=True)
        return
    ok = "ok " if r["verdict"] == r["truth"] else "MISS"
    look = f" look-alikes {r['lookalikes']} -> {r['after_experiment']}" if r["lookalikes"] else ""
    second = f" + {r['effects'][1]}" if len(r["effects"]) > 1 else ""
    print(f"{ok} seed {r['seed']} {r['system']:<11} {r['log']:<5} truth {r['truth']:<15} named "
          f"{r['named'] + second:<15} held-out shrink {r['shrink_pct']:6.1f}% confidence {r['confidence']} "
          f"calibrated {r['calibrated']} ({r['seconds']:.0f} s){look}  top: {r['ranking'][:3]}", flush=True)


def print_form_case(r):
    """One line per case of another family, as it finishes."""
    look = f" look-alikes {r['lookalikes']} -> {r.get('after_experiment')}" if r["lookalikes"] else ""
    cal = f" calibrated {r['calibrated']}" if r["calibration"] is not None else ""
    print(f"{'ok ' if r['right'] else 'MISS'} {r['family']} seed {r['seed']} {r['system']:<11} {r['log']:<5} "
          f"form {r['form']:<20} truth {r['truth']:<15} named {r['named']:<15} "
          f"held-out shrink {r['shrink_pct']:6.1f}% confidence {r['confidence']}{cal} "
          f"({r['seconds']:.0f} s){look}  top: {r['ranking'][:3]}", flush=True)


def main(argv=None):
    ap = leveler_cli.parser("leveler-blindtest", __doc__, "1 also when --check finds a target missed")
    ap.add_argument("--seeds", type=int, default=5, help="seeds per case (default 5)")
    ap.add_argument("--first-seed", type=int, default=1)
    ap.add_argument("--cases", default=",".join(CASES), help="comma-separated subset of cases")
    ap.add_argument("--system", choices=sorted(ALL_SYSTEMS),
                    help="only this system (default: rotate over the first three; 1000lb-accumulator only when asked)")
    # --log names a run-log file elsewhere (one name per thing): the kind is --log-kind, --log kept for old scripts
    ap.add_argument("--log-kind", "--log", dest="log", choices=sorted(LOG_KINDS),
                    help="only this log kind (default: rotate)")
    ap.add_argument("--shape", choices=("step", "walk"), default="step",
                    help="the logs: the thesis's step test (55 s), or a rig in service: 10-minute walks of "
                         f"{WALK_STEPS} load changes of random size and sign")
    ap.add_argument("--algorithm", type=int, choices=(1, 2, 3), default=None,
                    help="the rig's controller (default: each system config's)")
    ap.add_argument("--fast", action="store_true", help="smaller fitting budget (the CTest variant)")
    ap.add_argument("--out", "--keep", dest="keep", metavar="DIR",
                    help="keep logs, sealed labels and diagnoses here (default: a temporary folder)")
    ap.add_argument("--json", metavar="FILE", help="write all results here")
    ap.add_argument("--check", action="store_true", help="exit 1 when a target is missed")
    ap.add_argument("--min-hit", type=float, default=95.0, help="--check: least %% named right")
    ap.add_argument("--min-shrink", type=float, default=85.0, help="--check: least median shrink %% when right")
    ap.add_argument("--pairs", type=int, default=2, help="pair cases per seed (default 2)")
    ap.add_argument("--min-pairs", type=float, default=80.0,
                    help="--check: least %% of pair cases with both effects among the top two")
    ap.add_argument("--family", choices=FAMILIES + ("apart", "all"), default="present",
                    help="truth family: present (the first family, truth.json; default), offform (forms "
                         "written from the physics alone, truth2.json), unknown (effects outside the "
                         "catalogue), misset (one nominal parameter mis-set, no effect), apart (those three), "
                         "combo (a present effect on a mis-set rig), all")
    ap.add_argument("--forms", help="offform/unknown/misset/combo: comma-separated subset of forms")
    ap.add_argument("--report", metavar="FILE", help="print the family reports of a saved --json again and stop")
    ap.add_argument("--write-confidence", metavar="FILE",
                    help="with --report or a family run: write each confidence level's right / cases over the "
                         "offform and unknown cases (the diagnosis's data/confidence.json)")
    blindtest_run.add_options(ap)
    a = ap.parse_args(argv)
    if a.report:
        print_report(a.report)
        if a.write_confidence:
            with open(a.report) as fh:
                saved = json.load(fh)["results"]
            apart = [r for r in saved if r.get("family") in ("offform", "unknown")]
            write_confidence(a.write_confidence, apart, f"{len(apart)} offform/unknown cases, leveler "
                                                       f"{leveler.__version__}")
        return 0
    if a.family != "present":
        return main_families(a)
    cases = [c for c in a.cases.split(",") if c]
    for c in cases:
        if c not in CASES:
            ap.error(f"unknown case {c!r} (known: {', '.join(CASES)})")
    extra = blindtest_run.diagnosis_extra(a, ["--fast"] if a.fast else [], a.seeds * (len(cases) + a.pairs))
    top = a.keep or tempfile.mkdtemp(prefix="leveler-blindtest-")
    os.makedirs(top, exist_ok=True)
    force = (a.system, a.log, a.shape, a.algorithm)
    jobs = []
    for seed in range(a.first_seed, a.first_seed + a.seeds):
        for case in cases:
            jobs.append((len(jobs), "run_case", (top, seed, case, len(jobs), extra, force), {}))
        for j in range(a.pairs):
            jobs.append((len(jobs), "run_case", (top, seed, pair_case(seed, j, a.pairs), len(jobs), extra, force),
                         {"slot": len(CASES) + j}))
    t_all = time.perf_counter()
    done = blindtest_run.run_jobs(jobs, a, lambda job, r: print_case(r, "slot" in job[3]))
    results = [r for job, r in zip(jobs, done) if "slot" not in job[3]]
    pair_results = [r for job, r in zip(jobs, done) if "slot" in job[3]]
    print()
    print(confusion(results))
    s = summary(results)
    s.update(pair_summary(pair_results))
    print(f"\nright effect named: {s['right']}/{s['cases']} = {s['hit_pct']:.0f}% (target >= 95%)")
    print(f"median held-out shrink when right: {s['median_shrink_pct']:.1f}% (target >= 85%)")
    print(f"false effects in none cases: {s['false_in_none']}/{s['none_cases']} (target 0)")
    print(f"look-alikes reported: {s['lookalike_cases']}; right by system {s['by_system']}, by log {s['by_log']}")
    print(f"a second effect kept in single or none cases: {s['false_second']}/{s['cases']}")
    if pair_results:
        print(f"pairs, both effects among the top two: {s['pairs_both_top_two']}/{s['pair_cases']} "
              f"(target >= 80%, 8 of 10); both named (pair kept): {s['pairs_both_kept']}; "
              f"leader one of the two: {s['pairs_leader_right']}")
    print(f"median diagnosis time {s['median_seconds']:.1f} s ({1e3 * s['median_s_per_logged_s']:.0f} ms per s "
          f"of log); total {time.perf_counter() - t_all:.0f} s; "
          f"logs and diagnoses in {top}")
    if a.json:
        with open(a.json, "w") as fh:
            json.dump({"version": leveler.__version__, "results": results, "pair_results": pair_results, **s}, fh,
                      indent=2)
    if a.check:
        ok = s["hit_pct"] >= a.min_hit and (np.isnan(s["median_shrink_pct"]) or s["median_shrink_pct"] >= a.min_shrink) \
            and not s["false_in_none"] and (not pair_results or s["pairs_hit_pct"] >= a.min_pairs)
        return 0 if ok else 1
    return 0


def main_families(a):
    """--family other than present (all: present first, as main runs it, then the rest)."""
    fams = {"all": list(FAMILIES), "apart": list(APART)}.get(a.family, [a.family])
    top = a.keep or tempfile.mkdtemp(prefix="leveler-blindtest-")
    os.makedirs(top, exist_ok=True)
    rc, out = 0, {}
    if "present" in fams:
        argv = ["--seeds", str(a.seeds), "--first-seed", str(a.first_seed), "--keep", os.path.join(top, "present"),
                "--pairs", str(a.pairs), "--cases", a.cases] + (["--fast"] if a.fast else []) + (["--check"] if a.check else [])
        argv += (["--serial"] if a.serial else []) + (["--scheduler", a.scheduler] if a.scheduler else []) + \
            (["--workers", str(a.workers)] if a.workers else []) + ["--dashboard", a.dashboard]
        rc = main(argv + (["--json", a.json + ".present.json"] if a.json else []))
    forms = set(a.forms.split(",")) if a.forms else None
    force = (a.system, a.log, a.shape, a.algorithm)
    chosen = []
    for fam in [f for f in fams if f != "present"]:
        chosen += [sp for sp in family_specs(fam) if forms is None or sp["form"] in forms]
    extra = blindtest_run.diagnosis_extra(a, ["--fast"] if a.fast else [], a.seeds * len(chosen))
    jobs = []
    for fam in [f for f in fams if f != "present"]:
        specs = [sp for sp in chosen if sp["family"] == fam]
        for seed in range(a.first_seed, a.first_seed + a.seeds):
            for sp in specs:
                jobs.append((len(jobs), "run_form_case", (top, seed, sp, len(jobs), extra, force), {}))
    t_all = time.perf_counter()
    results = blindtest_run.run_jobs(jobs, a, lambda job, r: print_form_case(r))
    for fam in [f for f in fams if f != "present"]:
        fam_res = [r for r in results if r["family"] == fam]
        print()
        print("\n".join(family_report(fam_res)))
        out[fam] = {"right": sum(r["right"] for r in fam_res), "cases": len(fam_res)}
    print()
    print("\n".join(reliability(results)))
    if a.write_confidence:
        apart = [r for r in results if r["family"] in ("offform", "unknown")]
        write_confidence(a.write_confidence, apart, f"{len(apart)} offform/unknown cases, leveler "
                                                    f"{leveler.__version__}")
    print(f"total {time.perf_counter() - t_all:.0f} s; logs and diagnoses in {top}")
    if a.json:
        with open(a.json, "w") as fh:
            json.dump({"results": results, "families": out}, fh, indent=2, default=str)
    if a.check and any(100.0 * v["right"] / max(v["cases"], 1) < a.min_hit for v in out.values()):
        rc = 1      # --check: every family at --min-hit
    return rc


if __name__ == "__main__":
    sys.exit(main())

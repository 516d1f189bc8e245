"""The catalogue of candidate unmodelled effects, as written once in
host_sim/plant/effects.json (the C plant's table is generated from the same
file; the models are host_sim/plant/effects_candidates.c).

Each candidate is an optional extension of the C plant with a few parameters
in physically bounded ranges. All parameters at their `nominal` value
reproduce the nominal plant exactly. The order of `params` is the order of
the doubles passed to the C plant. `lo`/`hi` are the fitting bounds (`fit` in
the JSON); the C plant accepts the wider `range`.

Two effects at once (a pair) are named "a+b", the leader first: their
parameters are the two lists one after the other (parameter names are unique
across the catalogue), and the C plant runs both models (effects.h).
"""
import json
from dataclasses import dataclass

import numpy as np

from leveler import paths

CATALOGUE = paths.data("host_sim/plant/effects.json", "effects.json")


@dataclass(frozen=True)
class Param:
    name: str
    lo: float
    hi: float
    nominal: float
    log: bool = False   # fit in log space (time constants, areas spanning decades)
    doc: str = ""
    extends: bool = False   # extends the base model (nominal: the base), fitted after it
    knee: float = 0.0   # > 0: from lo = 0, linear below the knee and logarithmic above it


@dataclass(frozen=True)
class Effect:
    name: str
    effect_id: int      # effects.json id: what the C plant is called with
    params: tuple
    doc: str
    # sums of parameters that a log must resolve (effects.json "strokes"): a valve's delay
    # plus its lag, the time a stroke takes to be seen
    strokes: tuple = ()

    @property
    def names(self):
        return [p.name for p in self.params]

    def nominal(self):
        return {p.name: p.nominal for p in self.params}

    def resolved(self, values, interval_s):
        """Whether logs sampled every interval_s (s) resolve the fitted values: one of
        the strokes lasts at least one sample. A replayed log puts each switch anywhere
        within its sample, so a stroke shorter than that is the log's own timing, not
        evidence. Effects without strokes, and evidence without samples (interval 0),
        always are."""
        if not self.strokes or not interval_s > 0.0:
            return True
        return max(sum(values[n] for n in s) for s in self.strokes) >= interval_s


def _strokes(path, e):
    """An effect's "strokes": lists of its parameter names, checked."""
    out = tuple(tuple(s) for s in e.get("strokes", ()))
    names = {p["name"] for p in e["params"]}
    for s in out:
        if not s or not set(s) <= names:
            raise ValueError(f"{path}: effect {e['name']}: strokes: {list(s)} must name its parameters "
                             f"({', '.join(sorted(names))})")
    return out


def load(path=CATALOGUE):
    """The effects of a catalogue file, in its order."""
    with open(path) as fh:
        doc = json.load(fh)
    return tuple(Effect(e["name"], e["id"],
                        tuple(Param(p["name"], p["fit"][0], p["fit"][1], p["nominal"], p.get("log", False),
                                    p.get("doc", ""), p.get("extends", False), p.get("knee", 0.0))
                              for p in e["params"]),
                        e["doc"], _strokes(path, e))
                 for e in doc["effects"])


EFFECTS = load()
BY_NAME = {e.name: e for e in EFFECTS}
BY_ID = {e.effect_id: e for e in EFFECTS}
NAMES = [e.name for e in EFFECTS]


SEP = "+"          # joins the names of a pair: "leak+sensor_lag"
MAX_AT_ONCE = 2    # effects the C plant runs at once (PLANT_FX_MAX_MODELS)


def _single(name):
    try:
        return BY_NAME[name]
    except KeyError:
        raise KeyError(f"unknown effect {name!r}; known: {', '.join(NAMES)}") from None


def parts(name):
    """The single effects of a name: () for None/"none", ("a", "b") for "a+b"."""
    if not name or name == "none":
        return ()
    out = tuple(name.split(SEP))
    if len(out) > MAX_AT_ONCE or len(set(out)) != len(out):
        raise KeyError(f"{name!r}: at most {MAX_AT_ONCE} different effects at once")
    return out


def combine(names):
    """The name of effects taken together, in the order given."""
    return SEP.join(names)


def get(name):
    """A catalogued effect, or a pair "a+b" as one effect with both parameter lists."""
    names = parts(name)
    if len(names) == 1:
        return _single(names[0])
    singles = [_single(n) for n in names]
    return Effect(combine(names), None, tuple(p for e in singles for p in e.params),
                  " and ".join(e.doc for e in singles))


# The fit's unit box: [0, 1] per parameter, log-mapped where the range spans decades
# (from a knee where it starts at 0).
def _knee_span(p):
    return np.log1p((p.hi - p.lo) / p.knee)


def to_unit(effect, params):
    u = []
    for p in effect.params:
        v = min(max(params[p.name], p.lo), p.hi)
        if p.knee > 0.0:
            u.append(np.log1p((v - p.lo) / p.knee) / _knee_span(p))
        elif p.log:
            u.append((np.log(v) - np.log(p.lo)) / (np.log(p.hi) - np.log(p.lo)))
        else:
            u.append((v - p.lo) / (p.hi - p.lo))
    return np.array(u)


def from_unit(effect, u):
    out = {}
    for p, x in zip(effect.params, np.clip(u, 0.0, 1.0)):
        if p.knee > 0.0:   # times that span decades down to none at all (a valve's: 1 ms to 1 s, or 0)
            v = min(p.lo + p.knee * np.expm1(x * _knee_span(p)), p.hi)
        elif p.log:
            v = np.exp(np.log(p.lo) + x * (np.log(p.hi) - np.log(p.lo)))
        else:
            v = p.lo + x * (p.hi - p.lo)
        out[p.name] = float(v)
    return out

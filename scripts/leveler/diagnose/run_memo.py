"""What is worked out from a run's logged arrays alone (its times, signals,
commands, load and placed commands), kept while the run is in use: a fit
simulates the same two or three runs thousands of times, and the replay grid,
the chatter tracks and the residual's masks never change with the parameters
(runs are never changed in place). Keyed on the arrays' identities, so a copy
of a run with another start shift (dataclasses.replace shares the arrays)
finds them too; an entry holds the arrays it was keyed on, so an identity is
not reused by another array while it is cached. Arrays handed out are
read-only: a caller writing into one would change every later simulation."""
import collections

import numpy as np

SIZE = 256
_memo = collections.OrderedDict()


def _parts(run):
    return (run.t_s, run.signals, run.commands, getattr(run, "load_n", None), getattr(run, "fine_commands", None))


def _frozen(value):
    """value with every numpy array in it (in tuples, lists and dicts) made read-only."""
    if isinstance(value, np.ndarray):
        value.flags.writeable = False
    elif isinstance(value, (tuple, list)):
        for v in value:
            _frozen(v)
    elif isinstance(value, dict):
        for v in value.values():
            _frozen(v)
    return value


def of_run(run, name, compute):
    """compute(run), once per run's arrays and name."""
    parts = _parts(run)
    key = (name,) + tuple(id(p) for p in parts)
    hit = _memo.get(key)
    if hit is not None:
        _memo.move_to_end(key)
        return hit[1]
    value = _frozen(compute(run))
    _memo[key] = (parts, value)
    while len(_memo) > SIZE:
        _memo.popitem(last=False)
    return value


def clear():
    _memo.clear()

"""Where the gap lies: residual tables per phase and signal, event figures.

Residual = simulated - real, on the real run's time base. Signals are
weighted by fixed physical scales (SCALES) so that one number, the
normalised RMS, compares height and pressures.
"""
import functools
import os

import numpy as np

from . import phases as ph

# One unit of normalised error: 1 mm of height, 2 kPa of spring pressure,
# 5 kPa of pipe pressure (it swings with every compressor stroke), 2 kPa accumulator.
SCALES = {"height_m": 1.0e-3, "p_spring_pa": 2.0e3, "p_pipe_pa": 5.0e3, "p_acc_pa": 2.0e3}
SIGNAL_LABEL = {"height_m": "height", "p_spring_pa": "P2", "p_pipe_pa": "P1", "p_acc_pa": "P3"}
DISPLAY = {"height_m": (1e3, "mm"), "p_spring_pa": (1e-3, "kPa"), "p_pipe_pa": (1e-3, "kPa"),
           "p_acc_pa": (1e-3, "kPa")}


def shrink(before, after):
    """How far a gap shrinks, in percent of the gap before (0 when there is none)."""
    if not (before > 0 and np.isfinite(before) and np.isfinite(after)):
        return 0.0
    return float(100.0 * (1.0 - after / before))


def used_signals(run):
    return [s for s in SCALES if run.measured(s)]


def residuals(run, trace):
    """dict signal -> residual array (NaN where the real signal is not measured)."""
    out = {}
    for s in used_signals(run):
        sim = trace.signals.get(s)
        if sim is None:          # this simulator does not model the signal
            continue
        out[s] = sim - run.signals[s]
    return out


def gap_over_runs(runs, traces, labels=None):
    """Pooled normalised gap and per-signal RMS in display units over several runs."""
    sq = {}
    cnt = {}
    for i, (run, tr) in enumerate(zip(runs, traces)):
        for s, r in residuals(run, tr).items():
            m = np.isfinite(r)
            if labels is not None:
                m &= labels[i]
            sq[s] = sq.get(s, 0.0) + float(np.sum(r[m] ** 2))
            cnt[s] = cnt.get(s, 0) + int(m.sum())
    out = {}
    norm = []
    for s in sq:
        if cnt[s] == 0:
            continue
        rms = np.sqrt(sq[s] / cnt[s])
        k, unit = DISPLAY[s]
        out[f"rms_{SIGNAL_LABEL[s].lower()}_{unit.lower()}"] = rms * k
        norm.append((rms / SCALES[s]) ** 2)
    out["normalised"] = float(np.sqrt(np.mean(norm))) if norm else float("nan")
    return out


def phase_table(run, trace, labels):
    """Rows: phase x signal with bias, RMS (display units), samples and share of the gap."""
    res = residuals(run, trace)
    rows = []
    total = 0.0
    for p in ph.PHASES:
        m = labels == p
        if m.sum() == 0:
            continue
        for s, r in res.items():
            mm = m & np.isfinite(r)
            if mm.sum() == 0:
                continue
            k, unit = DISPLAY[s]
            e = float(np.sum((r[mm] / SCALES[s]) ** 2))
            total += e
            rows.append({"run": run.name, "phase": p, "signal": SIGNAL_LABEL[s], "unit": unit,
                         "bias": float(np.mean(r[mm]) * k), "rms": float(np.sqrt(np.mean(r[mm] ** 2)) * k),
                         "samples": int(mm.sum()), "_energy": e})
    for r in rows:
        r["share_pct"] = 100.0 * r.pop("_energy") / total if total > 0 else 0.0
    return rows


def rank_places(tables):
    """Merge phase tables of several runs; rank (phase, signal) by share of the gap."""
    merged = {}
    for rows in tables:
        for r in rows:
            key = (r["phase"], r["signal"])
            m = merged.setdefault(key, {"phase": r["phase"], "signal": r["signal"], "unit": r["unit"],
                                        "share_pct": 0.0, "bias_sum": 0.0, "sq_sum": 0.0, "samples": 0})
            m["share_pct"] += r["share_pct"] / len(tables)
            m["bias_sum"] += r["bias"] * r["samples"]
            m["sq_sum"] += r["rms"] ** 2 * r["samples"]
            m["samples"] += r["samples"]
    out = []
    for m in merged.values():
        n = max(m["samples"], 1)
        out.append({"phase": m["phase"], "signal": m["signal"], "unit": m["unit"],
                    "bias": m["bias_sum"] / n, "rms": float(np.sqrt(m["sq_sum"] / n)),
                    "share_pct": m["share_pct"], "samples": m["samples"]})
    out.sort(key=lambda r: -r["share_pct"])
    for i, r in enumerate(out, 1):
        r["rank"] = i
    return out


@functools.lru_cache(maxsize=16)
def band_of(config):
    """(band_lower_m, band_upper_m) of a plant config by name, as the C loader
    resolves it; the built-in config's for a name with no file (stand-in simulators)."""
    from leveler import config as config_mod

    from .cplant import config_path
    path = config_path(config)
    cfg = config_mod.load(path) if os.path.isfile(path) else config_mod.default_config()
    return cfg.band_lower_m, cfg.band_upper_m


def event_figures(t_s, signals, load_n, band):
    """Thesis event figures (leveler.events: flat snake_case SI keys) for the
    controller band (lower, upper) in m; undefined ones left out."""
    from types import SimpleNamespace

    from leveler import events
    log = SimpleNamespace(t_s=np.asarray(t_s), height_m=np.asarray(signals["height_m"]),
                          p_spring_pa=np.asarray(signals["p_spring_pa"]), load_n=np.asarray(load_n))
    out = events.summarize(log, events.EventOptions(band_lower_m=band[0], band_upper_m=band[1]))
    return {k: float(v) for k, v in out.items() if v is not None and np.isfinite(v)}


def event_differences(real, sim):
    return {k: sim[k] - real[k] for k in real if k in sim}

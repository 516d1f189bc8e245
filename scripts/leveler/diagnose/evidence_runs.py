"""Run logs as the diagnosis's evidence: phase x signal tables, event figures, the
residual signature of each candidate, the logs' own noise, pairs and experiments."""
import numpy as np

from . import candidates
from . import confidence
from . import fit
from . import gap
from . import phases as ph
from . import runs as runs_mod
from .evidence import FLOOR_MARGIN_PTS, THRESHOLD_PCT, Evidence, sensitivity_floor


def _labels(run):
    return ph.split(run.t_s, run.signals["height_m"], run.load_n)


def where_table(problem, runs):
    """Nominal simulation of each run, phase tables and the ranked places of the gap."""
    tables = []
    traces = []
    per_run = []
    for run in runs:
        tr = problem.simulate(run, None, {})
        labels = _labels(run)
        rows = gap.phase_table(run, tr, labels)
        tables.append(rows)
        traces.append(tr)
        band = gap.band_of(problem.config_of(run))
        ev_real = gap.event_figures(run.t_s, run.signals, run.load_n, band)
        ev_sim = gap.event_figures(tr.t_s, tr.signals, run.load_n, band)
        per_run.append({"run": run.name, "mode": fit.choose_mode(run, problem.mode),
                        "phases": ph.spans(run.t_s, labels), "table": rows,
                        "events_real": ev_real, "events_nominal": ev_sim,
                        "events_difference": gap.event_differences(ev_real, ev_sim)})
    return {"ranked": gap.rank_places(tables), "runs": per_run}, traces


def phase_gaps(runs, traces, labels):
    """Per phase the runs pass through: the gap of the traces over those samples (gap.gap_over_runs)."""
    out = {}
    for p in ph.PHASES:
        masks = [lab == p for lab in labels]
        if any(m.any() for m in masks):
            out[p] = gap.gap_over_runs(runs, traces, masks)
    return out


def before_after(problem, runs, nominal, augmented):
    """Held-out gaps overall and per phase, nominal vs augmented, and the shrink."""
    labels = [_labels(r) for r in runs]
    out = {"overall": {"before": gap.gap_over_runs(runs, nominal),
                       "after": gap.gap_over_runs(runs, augmented)}}
    b_all, a_all = phase_gaps(runs, nominal, labels), phase_gaps(runs, augmented, labels)
    out["per_phase"] = {p: {"before": b, "after": a_all[p], "shrink_pct": gap.shrink(b["normalised"],
                                                                                     a_all[p]["normalised"])}
                        for p, b in b_all.items()}
    ev = []
    for r, n, a in zip(runs, nominal, augmented):
        band = gap.band_of(problem.config_of(r))
        e_real = gap.event_figures(r.t_s, r.signals, r.load_n, band)
        ev.append({"run": r.name, "real": e_real,
                   "nominal": gap.event_figures(n.t_s, n.signals, r.load_n, band),
                   "augmented": gap.event_figures(a.t_s, a.signals, r.load_n, band)})
    out["events"] = ev
    return out


def _phase_energy(runs, traces, labels):
    """Per phase: summed normalised squared residual over runs."""
    out = {}
    for run, tr, lab in zip(runs, traces, labels):
        for sig, r in gap.residuals(run, tr).items():
            e = np.where(np.isfinite(r), (r / gap.SCALES[sig]) ** 2, 0.0)
            for p in ph.PHASES:
                out[p] = out.get(p, 0.0) + float(e[lab == p].sum())
    return out


def signatures(runs, problem, nominal, ranking):
    """Residual signature of each fitted candidate against the phase table (held-out):
    per-phase shrink, and how well the phases it fixes match where the gap lies
    (cosine of the nominal per-phase energy and the candidate's per-phase reduction),
    and the share of the nominal's residual it adds where it fits worse (confidence.worsened)."""
    labels = [_labels(r) for r in runs]
    e_nom = _phase_energy(runs, nominal, labels)
    before = {p: {"before": g["normalised"]} for p, g in phase_gaps(runs, nominal, labels).items()}
    phases = [p for p in ph.PHASES if e_nom.get(p, 0.0) > 0.0]
    v_nom = np.array([e_nom[p] for p in phases])
    for entry in ranking:
        aug = [problem.best_start(r, entry["effect"], candidates.values_of(entry))[0] for r in runs]
        e_aug = _phase_energy(runs, aug, labels)
        entry["per_phase_shrink_pct"] = {p: gap.shrink(np.sqrt(e_nom[p]), np.sqrt(e_aug.get(p, 0.0)))
                                         for p in phases}
        red = np.array([e_nom[p] - e_aug.get(p, 0.0) for p in phases])
        den = np.linalg.norm(v_nom) * np.linalg.norm(red)
        entry["signature_match"] = float(v_nom @ red / den) if den > 0 else 0.0
        entry["worsened_share"], entry["worsened_phases"] = confidence.worsened(entry, before)


def unexplained(hold_problem, holdout, ranking, kept, cal_gap, noise, threshold, progress):
    """confidence.unexplained on the best single or kept pair, with where the calibrated
    model's held-out residual lies per phase."""
    lead = dict(ranking[0])
    if kept and kept["shrink_pct"] > lead["shrink_pct"]:
        lead = {"effect": kept["effect"], "shrink_pct": kept["shrink_pct"]}
    cal_nominal = [hold_problem.best_start(r, None, {})[0] for r in holdout]
    per_phase = {p: {"before": g["normalised"]}
                 for p, g in phase_gaps(holdout, cal_nominal, [_labels(r) for r in holdout]).items()}
    finding = confidence.unexplained([lead], cal_gap, noise, per_phase, threshold)
    if finding:
        progress(f"      not explained by any candidate: {finding['why']}; the residual lies in "
                 + ", ".join(f"{w['phase']} ({w['gap']:.2f})" for w in finding["where"]))
    return finding


class RunLogs(Evidence):
    """Logged traces: every sample scored, against the logs' own noise."""

    noun = "runs"
    fits_pairs = True
    designs_experiments = True

    def where(self, problem, runs):
        return where_table(problem, runs)[0]

    def where_line(self, w):
        return (f"      #{w['rank']} {w['phase']:<10} {w['signal']:<6} bias {w['bias']:+.2f} {w['unit']}, "
                f"RMS {w['rms']:.2f} {w['unit']} ({w['share_pct']:.0f}% of the gap)")

    def threshold(self, hold_problem, nominal_hold_gap):
        floor = sensitivity_floor(hold_problem, nominal_hold_gap, hold_problem.start_shifts)
        return floor, max(THRESHOLD_PCT, floor + FLOOR_MARGIN_PTS)

    def signatures(self, holdout, hold_problem, ranking):
        signatures(holdout, hold_problem, [hold_problem.best_start(r, None, {})[0] for r in holdout], ranking)

    def noise_gap(self, holdout):
        return fit.noise_gap(holdout)

    def resolution_s(self, runs):
        return runs_mod.sample_interval(runs)

    unexplained = staticmethod(unexplained)
    before_after = staticmethod(before_after)

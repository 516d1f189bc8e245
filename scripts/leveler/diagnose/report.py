"""DIR/diagnosis.json and DIR/report.html (plots embedded as base64 PNG)."""
import base64
import html
import io
import json

import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from leveler.thesis import M_PER_IN, PA_PER_PSI  # noqa: E402


def _json_default(o):
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(type(o))


def _param_text(name, v):
    flags = [f for f, on in (("at its bound", v.get("at_bound")),
                             ("not identifiable", v.get("identifiable") is False),
                             ("refits on fewer runs outside", v.get("over_runs_within") is False)) if on]
    iv = v.get("interval")
    iv = f" ({iv[0]:.3g}..{iv[1]:.3g})" if iv else ""
    return f"{name}={v['value']:.3g}{iv} [{v['lo']:.3g}, {v['hi']:.3g}]" + (f" {', '.join(flags)}" if flags else "")


def _lookalike_html(result):
    """Look-alikes with their cross-fit evidence, and the proposed experiment."""
    parts = []
    group = result.get("cannot_tell_apart") or []
    if group:
        parts.append(f"<p><b>Cannot be told apart from these logs:</b> {html.escape(', '.join(group))}. "
                     "Each, refitted on the runs the other would make, explains them as well as it "
                     "explains the real runs.</p>")
    if result.get("separability"):
        parts.append(_table(result["separability"], [
            ("A / B", lambda r: " / ".join(r["effects"])),
            ("B refitted on A's runs: gap", lambda r: r["b_on_a_gap"]), ("A's own gap", lambda r: r["a_own_gap"]),
            ("A refitted on B's runs: gap", lambda r: r["a_on_b_gap"]), ("B's own gap", lambda r: r["b_own_gap"]),
            ("told apart", lambda r: "no" if r["cannot_tell_apart"] else "yes")]))
    exp = result.get("experiment")
    if exp:
        parts.append(f"<h3>Proposed experiment: {html.escape(' vs '.join(exp['between']))} "
                     "(experiment.csv, a <code>leveler-sim --schedule</code> file)</h3>")
        parts.append(_table(exp["ranked"], [
            ("schedule", lambda r: r["schedule"]), ("kind", lambda r: r.get("kind", "load")),
            ("predicted difference / sensor noise", lambda r: r["separation_noise_units"])]))
        if exp.get("unsafe"):
            parts.append("<p>Left out (the supervisor would override them): "
                         f"{html.escape(', '.join(exp['unsafe']))}</p>")
    return parts


def write_json(path, result):
    """Strict JSON: NaN/inf (a figure that could not be computed) become null."""
    with open(path, "w") as fh:
        json.dump(_clean(result), fh, indent=2, default=_json_default, allow_nan=False)
        fh.write("\n")


def _clean(o):
    if isinstance(o, (float, np.floating)):
        return float(o) if np.isfinite(o) else None
    if isinstance(o, dict):
        return {k: _clean(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_clean(v) for v in o]
    return o


def _png(fig):
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90, bbox_inches="tight")
    plt.close(fig)
    return base64.b64encode(buf.getvalue()).decode("ascii")


def _trace_plot(run, nom, aug, effect):
    fig, axes = plt.subplots(3, 1, figsize=(9, 7.5), sharex=True)
    for ax, sig, k, unit in ((axes[0], "height_m", 1e3, "height (mm)"),
                             (axes[1], "p_spring_pa", 1e-3, "P2 (kPa abs)"),
                             (axes[2], "p_pipe_pa", 1e-3, "P1 (kPa abs)")):
        ax.plot(run.t_s, run.signals[sig] * k, color="k", lw=1.0, label="real")
        ax.plot(nom.t_s, nom.signals[sig] * k, color="tab:blue", lw=1.0, label="nominal")
        if effect != "none":
            ax.plot(aug.t_s, aug.signals[sig] * k, color="tab:red", lw=1.0, ls="--", label=f"+ {effect}")
        ax.set_ylabel(unit)
        ax.grid(alpha=0.3)
    axes[0].legend(loc="best", fontsize=8)
    axes[-1].set_xlabel("t (s)")
    axes[0].set_title(run.name)
    return _png(fig)


def _loop_plot(run, nom, aug, effect):
    fig, ax = plt.subplots(figsize=(6, 5))
    ax.plot(run.signals["p_spring_pa"] * 1e-3, run.signals["height_m"] * 1e3, "k", lw=1, label="real")
    ax.plot(nom.signals["p_spring_pa"] * 1e-3, nom.signals["height_m"] * 1e3, color="tab:blue", lw=1,
            label="nominal")
    if effect != "none":
        ax.plot(aug.signals["p_spring_pa"] * 1e-3, aug.signals["height_m"] * 1e3, color="tab:red", lw=1,
                ls="--", label=f"+ {effect}")
    ax.set_xlabel("P2 (kPa abs)")
    ax.set_ylabel("height (mm)")
    ax.set_title(f"P2 against height: {run.name}")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return _png(fig)


def _table(rows, cols):
    h = ["<table><tr>" + "".join(f"<th>{html.escape(c)}</th>" for c, _ in cols) + "</tr>"]
    for r in rows:
        cells = []
        for _, f in cols:
            v = f(r)
            cells.append(f"<td>{html.escape(v if isinstance(v, str) else f'{v:.3g}')}</td>")
        h.append("<tr>" + "".join(cells) + "</tr>")
    h.append("</table>")
    return "\n".join(h)


def _second_text(result):
    """The ranked combination's second place, in words."""
    sec = result.get("second")
    if not sec or not sec.get("pair"):
        return ""
    lead = result["ranking"][0]["effect"]
    return (f" Ranked second: <code>{html.escape(sec['effect'])}</code>, the effect that best explains what "
            f"<code>{html.escape(lead)}</code> leaves (pair evidence {sec['evidence']:+.1f} log-likelihood units, "
            f"{sec['gain_pts']:+.1f} held-out points over the leader"
            + (")." if sec["kept"] else "; not named: see the table).") +
            " Pairs marked as screening fits were fitted briefly, to rank; the others in full, to judge.")


def _pairs_html(result):
    """Pairs fitted on top of the leader, and whether a second effect is kept."""
    if not result.get("pairs"):
        return []
    kept = len(result.get("effects") or []) > 1
    parts = ["<h2>Two effects at once (pairs on top of the leader, held-out)</h2>",
             "<p>" + (f"Kept: <code>{html.escape(' + '.join(result['effects']))}</code>." if kept else
                      "No second effect is kept.") +
             _second_text(result) +
             " A second effect is kept when the pair closes at least 30 % of the held-out gap the leader "
             "leaves (and 5 points of the nominal gap), clears the threshold, lowers the information criterion on the calibration "
             "residuals (the fit gain pays for its parameters), and neither effect alone makes the held-out "
             "gap worse than nominal.</p>"]
    parts.append(_table(result["pairs"], [
        ("pair", lambda r: " + ".join(r["effects"])), ("held-out shrink %", lambda r: r["shrink_pct"]),
        ("gain over the leader, points", lambda r: r["gain_pts"]),
        ("share of the leader's gap closed %", lambda r: r["closes_pct_of_leader_gap"]),
        ("calibration shrink %", lambda r: r["calibration_shrink_pct"]),
        ("information criterion change", lambda r: r["delta_bic"]),
        ("evidence over the leader", lambda r: r["evidence"]),
        ("kept", lambda r: "yes" if r["kept"] else "no: " + "; ".join(r["why_not"])),
        ("parameters: value (95 % interval) [range] flags", lambda r: "; ".join(
            _param_text(k, v) for k, v in r["params"].items()))]))
    return parts


def write_html(path, result, traces):
    eff = " + ".join(result.get("effects") or []) or result["effect"]
    parts = [
        "<!doctype html><html><head><meta charset='utf-8'><title>leveler diagnosis</title>",
        "<style>body{font-family:sans-serif;max-width:1000px;margin:auto}"
        "table{border-collapse:collapse;margin:1em 0}td,th{border:1px solid #bbb;padding:2px 6px;"
        "font-size:90%}th{background:#eee}</style></head><body>",
        f"<h1>Sim-to-real diagnosis: {html.escape(result['config'])}</h1>",
        f"<p>Calibration runs: {html.escape(', '.join(result['calibration_runs']))}. "
        f"Held-out runs: {html.escape(', '.join(result['holdout_runs']))}.</p>",
        f"<h2>Verdict: <code>{html.escape(eff)}</code></h2>",
    ]
    if eff != "none":
        parts.append(f"<p>Held-out gap shrinks by {result['shrink_pct']:.1f}% "
                     f"(margin over {html.escape(str(result['runner_up']))}: {result['margin_pct']:.1f} points; "
                     f"threshold {result['threshold_pct']:.0f}%).</p>")
    else:
        parts.append(f"<p>No candidate shrinks the held-out gap by {result['threshold_pct']:.0f}% or more.</p>")
    parts += _lookalike_html(result)
    parts += _pairs_html(result)
    gb, ga = result["gap_before"], result["gap_after"]
    parts.append(_table([{"k": k, "b": gb[k], "a": ga.get(k, float('nan'))} for k in gb],
                        [("held-out gap", lambda r: r["k"]), ("nominal", lambda r: r["b"]),
                         ("augmented", lambda r: r["a"])]))
    parts.append("<h2>Ranking of candidate effects (held-out)</h2>")
    parts.append(_table(result["ranking"], [
        ("rank", lambda r: str(r["rank"])), ("effect", lambda r: r["effect"]),
        ("held-out shrink %", lambda r: r["shrink_pct"]),
        ("calibration shrink %", lambda r: r["calibration_shrink_pct"]),
        ("held-out gap", lambda r: r["holdout_gap"]),
        ("signature match", lambda r: r.get("signature_match", float("nan"))),
        ("parameters: value (95 % interval) [range] flags", lambda r: "; ".join(
            _param_text(k, v) for k, v in r["params"].items()))]))
    parts.append("<h2>Where the gap lies (nominal model, all runs)</h2>")
    ranked = result["where"]["ranked"]
    if ranked and "figure" in ranked[0]:
        num = lambda v: "-" if v is None else v
        parts.append(_table(ranked, [
            ("rank", lambda r: str(r["rank"])), ("run", lambda r: r["run"]), ("figure", lambda r: r["figure"]),
            ("phase", lambda r: r["phase"]), ("published (SI)", lambda r: num(r["published"])),
            ("nominal (SI)", lambda r: num(r["simulated"])),
            ("difference / resolution", lambda r: num(r["normalised"]))]))
        ranked = []
    parts.append(_table(ranked[:16], [
        ("rank", lambda r: str(r["rank"])), ("phase", lambda r: r["phase"]), ("signal", lambda r: r["signal"]),
        ("bias", lambda r: r["bias"]), ("RMS", lambda r: r["rms"]), ("unit", lambda r: r["unit"]),
        ("share %", lambda r: r["share_pct"])]))
    parts.append("<h2>Per phase, held-out (normalised gap)</h2>")
    parts.append(_table([{"p": p, **v} for p, v in result["per_phase"].items()], [
        ("phase", lambda r: r["p"]), ("nominal", lambda r: r["before"]["normalised"]),
        ("augmented", lambda r: r["after"]["normalised"]), ("shrink %", lambda r: r["shrink_pct"])]))
    for ev in result["events"]:
        if not ev["real"]:
            continue
        parts.append(f"<h3>Event figures: {html.escape(ev['run'])}</h3>")
        parts.append(_table([{"k": k} for k in ev["real"]], [
            ("figure", lambda r: r["k"]), ("real", lambda r: ev["real"][r["k"]]),
            ("nominal", lambda r: ev["nominal"].get(r["k"]) or float("nan")),
            ("augmented", lambda r: ev["augmented"].get(r["k"]) or float("nan"))]))
    if traces:
        parts.append("<h2>Traces (held-out)</h2>")
        for run, nom, aug in zip(traces["holdout"], traces["nominal"], traces["augmented"]):
            if not hasattr(run, "signals"):
                continue
            parts.append(f"<img src='data:image/png;base64,{_trace_plot(run, nom, aug, eff)}'>")
            parts.append(f"<img src='data:image/png;base64,{_loop_plot(run, nom, aug, eff)}'>")
    parts.append("</body></html>")
    with open(path, "w") as fh:
        fh.write("\n".join(parts))

"""DIR/diagnosis.json and DIR/report.html (templates/report.html.j2, Jinja2; plots embedded as base64 PNG)."""
import base64
import io
import json

import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import jinja2  # noqa: E402

from leveler import __version__  # noqa: E402
from leveler.thesis import M_PER_IN, PA_PER_PSI  # noqa: E402
from leveler.diagnose import effects as fx  # noqa: E402

_TEMPLATES = jinja2.Environment(loader=jinja2.PackageLoader("leveler.diagnose", "templates"),
                                autoescape=True, undefined=jinja2.StrictUndefined,
                                trim_blocks=True, lstrip_blocks=True)


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


def _lookalikes(result):
    """Look-alikes with their cross-fit evidence, and the proposed experiment (template data)."""
    sep = result.get("separability")
    exp = result.get("experiment")
    return {
        "group": result.get("cannot_tell_apart") or [],
        "separability": _table(sep, [
            ("A / B", lambda r: " / ".join(r["effects"])),
            ("B refitted on A's runs: gap", lambda r: r["b_on_a_gap"]), ("A's own gap", lambda r: r["a_own_gap"]),
            ("A refitted on B's runs: gap", lambda r: r["a_on_b_gap"]), ("B's own gap", lambda r: r["b_own_gap"]),
            ("told apart", lambda r: "no" if r["cannot_tell_apart"] else "yes")]) if sep else None,
        "experiment": {"between": exp["between"], "unsafe": exp.get("unsafe") or [], "table": _table(exp["ranked"], [
            ("schedule", lambda r: r["schedule"]), ("kind", lambda r: r.get("kind", "load")),
            ("predicted difference / sensor noise", lambda r: r["separation_noise_units"])]
            + ([("each from no effect / sensor noise", lambda r: r["each_shows_noise_units"])]
               if any("each_shows_noise_units" in r for r in exp["ranked"]) else []))} if exp else None,
    }


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
    """A table for the template's table macro: the column titles and each row's
    cells as text (numbers to 3 significant digits)."""
    return {"head": [c for c, _ in cols],
            "rows": [[v if isinstance(v, str) else f"{v:.3g}" for v in (f(r) for _, f in cols)] for r in rows]}


def _second(result):
    """The ranked combination's second place (template data), or None."""
    sec = result.get("second")
    if not sec or not sec.get("pair"):
        return None
    return {"effect": sec["effect"], "lead": fx.parts(sec["pair"])[0], "evidence": sec["evidence"],
            "gain_pts": sec["gain_pts"], "kept": sec["kept"]}


def _pairs(result):
    """Pairs fitted on top of the leader, and whether a second effect is kept (template data), or None."""
    if not result.get("pairs"):
        return None
    return {"kept": len(result.get("effects") or []) > 1, "effects": result.get("effects") or [],
            "second": _second(result), "table": _table(result["pairs"], [
                ("pair", lambda r: " + ".join(r["effects"])), ("held-out shrink %", lambda r: r["shrink_pct"]),
                ("gain over its first, points", lambda r: r["gain_pts"]),
                ("share of the leader's gap closed %", lambda r: r["closes_pct_of_leader_gap"]),
                ("calibration shrink %", lambda r: r["calibration_shrink_pct"]),
                ("information criterion change", lambda r: r["delta_bic"]),
                ("evidence over the leader", lambda r: r["evidence"]),
                ("kept", lambda r: "yes" if r["kept"] else "no: " + "; ".join(r["why_not"])),
                ("parameters: value (95 % interval) [range] flags", lambda r: "; ".join(
                    _param_text(k, v) for k, v in r["params"].items()))])}


def _where_tables(result):
    """The gap's location: published figures (feature runs), else phase/signal rows."""
    ranked = result["where"]["ranked"]
    if ranked and "figure" in ranked[0]:
        num = lambda v: "-" if v is None else v
        return [_table(ranked, [
            ("rank", lambda r: str(r["rank"])), ("run", lambda r: r["run"]), ("figure", lambda r: r["figure"]),
            ("phase", lambda r: r["phase"]), ("published (SI)", lambda r: num(r["published"])),
            ("nominal (SI)", lambda r: num(r["simulated"])),
            ("difference / resolution", lambda r: num(r["normalised"]))])]
    return [_table(ranked[:16], [
        ("rank", lambda r: str(r["rank"])), ("phase", lambda r: r["phase"]), ("signal", lambda r: r["signal"]),
        ("bias", lambda r: r["bias"]), ("RMS", lambda r: r["rms"]), ("unit", lambda r: r["unit"]),
        ("share %", lambda r: r["share_pct"])])]


def _event_tables(result):
    return [{"run": ev["run"], "table": _table([{"k": k} for k in ev["real"]], [
        ("figure", lambda r: r["k"]), ("real", lambda r: ev["real"][r["k"]]),
        ("nominal", lambda r: ev["nominal"].get(r["k"]) or float("nan")),
        ("augmented", lambda r: ev["augmented"].get(r["k"]) or float("nan"))])}
        for ev in result["events"] if ev["real"]]


def _trace_images(traces, eff):
    if not traces:
        return []
    return [img for run, nom, aug in zip(traces["holdout"], traces["nominal"], traces["augmented"])
            if hasattr(run, "signals")
            for img in (_trace_plot(run, nom, aug, eff), _loop_plot(run, nom, aug, eff))]


def _calibration_table(cal):
    """The calibration stage's parameters (calibrate.py), or None when it did not run."""
    if not cal:
        return None
    return _table(cal["parameters"], [
        ("parameter", lambda p: p["name"]), ("config", lambda p: p["config"]),
        ("calibrated", lambda p: p["value"]), ("change %", lambda p: p["change_pct"]),
        ("95 % interval", lambda p: f"{p['interval'][0]:.4g} .. {p['interval'][1]:.4g}"),
        ("flags", lambda p: ", ".join(f for f, on in (("moved", p["moved"]), ("not identifiable",
                                                      not p["identifiable"]), ("at its bound", p["at_bound"])) if on)),
        ("what it sets", lambda p: p["why"])])


def write_html(path, result, traces):
    """report.html from templates/report.html.j2 (Jinja2, autoescaped)."""
    eff = " + ".join(result.get("effects") or []) or result["effect"]
    gb, ga = result["gap_before"], result["gap_after"]
    page = _TEMPLATES.get_template("report.html.j2").render(
        r=result, eff=eff, version=result.get("version") or __version__,
        lookalikes=_lookalikes(result), pairs=_pairs(result),
        gap=_table([{"k": k, "b": gb[k], "a": ga.get(k, float("nan"))} for k in gb],
                   [("held-out gap", lambda r: r["k"]), ("nominal", lambda r: r["b"]),
                    ("augmented", lambda r: r["a"])]),
        ranking=_table(result["ranking"], [
            ("rank", lambda r: str(r["rank"])), ("effect", lambda r: r["effect"]),
            ("held-out shrink %", lambda r: r["shrink_pct"]),
            ("calibration shrink %", lambda r: r["calibration_shrink_pct"]),
            ("held-out gap", lambda r: r["holdout_gap"]),
            ("signature match", lambda r: r.get("signature_match", float("nan"))),
            ("parameters: value (95 % interval) [range] flags", lambda r: "; ".join(
                _param_text(k, v) for k, v in r["params"].items()))]),
        calibration=_calibration_table(result.get("calibration")),
        where=_where_tables(result),
        per_phase=_table([{"p": p, **v} for p, v in result["per_phase"].items()], [
            ("phase", lambda r: r["p"]), ("nominal", lambda r: r["before"]["normalised"]),
            ("augmented", lambda r: r["after"]["normalised"]), ("shrink %", lambda r: r["shrink_pct"])]),
        events=_event_tables(result), images=_trace_images(traces, eff))
    with open(path, "w", encoding="utf-8") as fh:
        fh.write(page)

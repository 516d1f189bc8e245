"""`leveler-diagnose --write-config FILE`: the rig's model as the diagnosis found
it, as a config the whole product runs (docs/config-format.md): an `include` of
the user's config, the calibrated nominal values as ordinary keys and the named
effect(s) as [effect.NAME] sections, each with a comment saying where it came
from and its 95 % interval. The values are the very floats the diagnosis's
held-out figures were simulated with (diagnosis.json `model`), written so that
they read back exactly (repr), so `leveler-compare --config FILE` gives the
diagnosis's own after-gap."""
import os
import time

from leveler import runlog


def _interval(iv, value):
    """The 95 % interval when it is the value's (a joint fit moves the value away from
    the interval of the fit alone: then none is claimed)."""
    if iv and iv[0] <= value <= iv[1]:
        return f", 95 % interval {iv[0]:.6g}..{iv[1]:.6g}"
    return ", no interval (fitted jointly)" if iv else ""


def _key_note(k):
    if not k["chosen"]:
        return "not fitted: the config's value"
    span = _interval(k.get("interval"), k["value"])
    state = "calibrated" if k["moved"] else "fitted, not moved"
    rel = (k["value"] / k["config"] - 1.0) * 100.0 if k.get("config") else 0.0
    return f"{state}: config {k['config']:.6g}, {rel:+.1f} %{span}"


def _effect_note(effect, p):
    return f"fitted ({effect})" + _interval(p.get("interval"), p["value"])


def text(result, name, version):
    """The config text of diagnosis result `result` (with its `model`), named `name`."""
    m = result["model"]
    head = [f"; written by leveler-diagnose {version} on {time.strftime('%Y-%m-%d %H:%M:%S')}",
            f"; calibration runs: {', '.join(result['calibration_runs'])}; held out: "
            f"{', '.join(result['holdout_runs'])}",
            f"; effect: {' + '.join(result['effects']) or 'none'}; held-out gap "
            f"{result['gap_before']['normalised']:.4f} -> {result['gap_after']['normalised']:.4f} "
            f"(shrink {result['shrink_pct']:.1f} %)",
            "", "[config]", f"include = {m['config']}", f"name = {name}"]
    sections = {}
    for k in m["keys"]:
        sections.setdefault(k["section"], []).append(f"{k['key']} = {k['value']!r}  ; {_key_note(k)}")
    for effect, params in m["effects"].items():
        sections[f"effect.{effect}"] = [f"{q} = {p['value']!r}  ; {_effect_note(effect, p)}"
                                        for q, p in params.items()]
    body = [f"\n[{sec}]\n" + "\n".join(lines) for sec, lines in sections.items()]
    return "\n".join(head) + "\n" + "\n".join(body) + "\n"


def write(path, result, name, version):
    """Writes the config atomically (never half a file; runlog's writer)."""
    if not result.get("model"):
        raise ValueError("this diagnosis has no model to write (published figures)")
    runlog.write_text_atomic(os.path.abspath(path), text(result, name, version))

#!/usr/bin/env python3
"""Writes the C table of an effect catalogue (host_sim/plant/effects.json, the
blind test's host_sim/blindtest/truth.json): one plant_fx_model per effect
with its name, id, parameter count, parameter names, accepted ranges and
nominal values (NaN where a catalogue has none), tied to the model's functions
by name (<ops_prefix><name>_ops). Python loads the same JSON; the config loader
reads [effect.NAME] sections by these names (host_sim/plant/plant_config_effects.c).

  gen_effects.py CATALOGUE.json OUT.c --table NAME --ops-prefix PREFIX

System python3, standard library only (a build step, like gen_regmap.py).
"""
import argparse
import json
import sys

MAX_PARAMS = 8   # PLANT_FX_MAX_PARAMS in host_sim/plant/effects.h


def table(doc, name, ops_prefix, source):
    lines = [f"/* Generated from {source} by scripts/gen_effects.py: do not edit. */",
             '#include "effects.h"', ""]
    effects = doc["effects"]
    seen = set()
    for e in effects:
        if not e["name"].isidentifier() or e["name"] in seen or e["id"] in seen:
            raise ValueError(f"{source}: effect {e['name']!r}: names and ids must be unique identifiers")
        seen.update((e["name"], e["id"]))
        if not 1 <= len(e["params"]) <= MAX_PARAMS:
            raise ValueError(f"{source}: effect {e['name']}: 1..{MAX_PARAMS} parameters")
        for p in e["params"]:
            lo, hi = p["range"]
            if not lo <= hi:
                raise ValueError(f"{source}: {e['name']}.{p['name']}: range must rise")
            if not p["name"].isidentifier():
                raise ValueError(f"{source}: {e['name']}.{p['name']}: parameter names are identifiers")
        lines.append(f"extern const plant_fx_ops {ops_prefix}{e['name']}_ops;")
    lines += ["", f"const plant_fx_model {name}[] = {{"]
    for e in effects:
        lo = ", ".join(repr(float(p["range"][0])) for p in e["params"])
        hi = ", ".join(repr(float(p["range"][1])) for p in e["params"])
        names = ", ".join(f'"{p["name"]}"' for p in e["params"])
        nominal = ", ".join(repr(float(p["nominal"])) if "nominal" in p else '__builtin_nan("")'
                            for p in e["params"])
        lines.append(f'    {{"{e["name"]}", {e["id"]}, {len(e["params"])}, {{{lo}}}, {{{hi}}}, '
                     f'&{ops_prefix}{e["name"]}_ops, {{{names}}}, {{{nominal}}}}},')
    lines += ["};", f"const int {name}_count = {len(effects)};", ""]
    return "\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("catalogue")
    ap.add_argument("out")
    ap.add_argument("--table", required=True)
    ap.add_argument("--ops-prefix", required=True)
    a = ap.parse_args(argv)
    with open(a.catalogue) as fh:
        doc = json.load(fh)
    text = table(doc, a.table, a.ops_prefix, a.catalogue.split("/host_sim/")[-1])
    with open(a.out, "w") as fh:
        fh.write(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())

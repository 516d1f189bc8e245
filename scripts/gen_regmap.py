#!/usr/bin/env python3
"""Register-map generator: firmware/regmap/registers.json -> C header, C table, docs.

    gen_regmap.py JSON --header OUT.h --table OUT.c     (run by CMake at build time)
    gen_regmap.py JSON --doc docs/registers.md           (cmake --build B --target regmap-docs)
    gen_regmap.py JSON --doc -                           (print the doc; the drift test)
    gen_regmap.py JSON --tags OUT.csv                    (the HMI/SCADA tag export, installed with the docs)

Standard library only: the cross build runs it with the system python3.
Every error names the JSON file, the entry (index and name) and the field.
"""
import argparse
import json
import re
import sys

TABLES = {  # json name -> (C enum, macro prefix, title, modbus functions)
    "coil": ("LEVELER_TABLE_COIL", "COIL", "Coils", "FC 01/05/15"),
    "discrete": ("LEVELER_TABLE_DISCRETE_INPUT", "DI", "Discrete inputs", "FC 02"),
    "holding": ("LEVELER_TABLE_HOLDING_REGISTER", "HR", "Holding registers", "FC 03/06/16"),
    "input": ("LEVELER_TABLE_INPUT_REGISTER", "IR", "Input registers", "FC 04"),
}
TABLE_ORDER = ["input", "discrete", "coil", "holding"]
TYPES = {  # json type -> (C enum, words, min allowed, max allowed)
    "bit": ("LEVELER_REGTYPE_BIT", 1, 0, 1),
    "uint16": ("LEVELER_REGTYPE_U16", 1, 0, 0xFFFF),
    "int32": ("LEVELER_REGTYPE_I32", 2, -(2 ** 31), 2 ** 31 - 1),
    "uint32": ("LEVELER_REGTYPE_U32", 2, 0, 2 ** 32 - 1),
}
BIT_TABLES = ("coil", "discrete")
ACCESS = {"R": "LEVELER_ACCESS_R", "RW": "LEVELER_ACCESS_RW"}
BIND_STRUCTS = {  # bind prefix -> (C region enum, C struct type)
    "status": ("LEVELER_REGION_STATUS", "leveler_status"),
    "settings": ("LEVELER_REGION_SETTINGS", "leveler_settings"),
    "command": ("LEVELER_REGION_COMMAND", "leveler_command"),
}
BIND_RE = re.compile(r"^(status|settings|command)\.([A-Za-z_][A-Za-z0-9_]*(\[[0-9]+\])?(\.[A-Za-z_][A-Za-z0-9_]*)?)$")
NAME_RE = re.compile(r"^[a-z][a-z0-9_]*$")
REQUIRED = ("name", "table", "address", "type", "scale", "unit", "range", "access", "bind", "description")


class RegmapError(Exception):
    pass


def load(path):
    try:
        with open(path, encoding="utf-8") as f:
            text = f.read()
    except OSError as e:
        raise RegmapError(f"{path}: cannot read: {e.strerror}")
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as e:
        raise RegmapError(f"{path}:{e.lineno}:{e.colno}: invalid JSON: {e.msg}")
    if not isinstance(doc, dict) or not isinstance(doc.get("registers"), list):
        raise RegmapError(f"{path}: top level must be an object with a 'registers' list")
    return doc


def entry_line(text, index):
    """Line of the index-th register object in the JSON text (for error messages)."""
    count = -1
    for lineno, line in enumerate(text.splitlines(), 1):
        if re.match(r'^\s*"name"\s*:', line):
            count += 1
            if count == index:
                return lineno
    return 0


def validate(path, doc):
    with open(path, encoding="utf-8") as f:
        text = f.read()
    errors = []
    seen_names = {}
    occupied = {t: {} for t in TABLES}  # table -> address -> entry name
    regs = doc["registers"]
    for i, r in enumerate(regs):
        where = f"{path}:{entry_line(text, i)}: register #{i} ({r.get('name', '?') if isinstance(r, dict) else '?'})"

        def err(field, msg):
            errors.append(f"{where}: field '{field}': {msg}")

        if not isinstance(r, dict):
            errors.append(f"{where}: must be an object")
            continue
        missing = [k for k in REQUIRED if k not in r]
        for k in missing:
            err(k, "missing")
        if missing:
            continue
        name = r["name"]
        if not isinstance(name, str) or not NAME_RE.match(name):
            err("name", f"{name!r} is not a lower-case C identifier")
        elif name in seen_names:
            err("name", f"duplicate of register #{seen_names[name]}")
        else:
            seen_names[name] = i
        table, typ, access = r["table"], r["type"], r["access"]
        ok = True
        if table not in TABLES:
            err("table", f"unknown table {table!r} (one of {', '.join(TABLES)})"); ok = False
        if typ not in TYPES:
            err("type", f"unknown type {typ!r} (one of {', '.join(TYPES)})"); ok = False
        if access not in ACCESS:
            err("access", f"unknown access {access!r} (R or RW)"); ok = False
        addr = r["address"]
        if not isinstance(addr, int) or isinstance(addr, bool) or not 0 <= addr <= 0xFFFF:
            err("address", f"{addr!r} is not an integer 0..65535"); ok = False
        bind = r["bind"]
        m = BIND_RE.match(bind) if isinstance(bind, str) else None
        if not m:
            err("bind", f"unknown bind {bind!r} (status.<field>, settings.<field> or command.<field>)"); ok = False
        rng = r["range"]
        if (not isinstance(rng, list) or len(rng) != 2 or not all(isinstance(v, int) and not isinstance(v, bool) for v in rng)
                or rng[0] > rng[1]):
            err("range", f"{rng!r} is not [min, max] integers with min <= max"); ok = False
        if not ok:
            continue
        if (table in BIT_TABLES) != (typ == "bit"):
            err("type", f"type {typ!r} does not fit table {table!r} (bits only in coil/discrete)")
        if table in ("input", "discrete") and access != "R":
            err("access", f"table {table!r} is read-only")
        if m.group(1) == "settings" and table != "holding":
            err("access", "settings are holding registers")
        if m.group(1) == "settings" and access == "R" and "default" not in r:
            # R settings are the firmware's own records kept in flash (commissioning result)
            err("access", "a read-only setting needs a default")
        if m.group(1) == "status" and access != "R":
            err("access", "status is read-only (R)")
        _, words, tmin, tmax = TYPES[typ]
        if rng[0] < tmin or rng[1] > tmax:
            err("range", f"{rng} does not fit type {typ} ({tmin}..{tmax})")
        if words == 2 and addr % 2:
            err("address", f"32-bit value at odd address {addr} (must start on an even slot)")
        for a in range(addr, addr + words):
            if a in occupied[table]:
                err("address", f"{table} address {a} overlaps register {occupied[table][a]!r}")
            else:
                occupied[table][a] = name
        if "default" in r:
            d = r["default"]
            if not isinstance(d, int) or isinstance(d, bool):
                err("default", f"{d!r} is not an integer")
            elif not rng[0] <= d <= rng[1]:
                err("default", f"{d} outside range {rng}")
        elif m.group(1) == "settings":
            err("default", "missing (every setting needs a factory default)")
        if "enum" in r:
            e = r["enum"]
            if not isinstance(e, dict) or not e:
                err("enum", "must be a non-empty object name -> value")
            else:
                for k, v in e.items():
                    if not isinstance(v, int) or not rng[0] <= v <= rng[1]:
                        err("enum", f"value {k!r}: {v!r} outside range {rng}")
                if "default" in r and r["default"] not in e.values():
                    err("default", f"{r['default']} is not one of the enum values")
        if not isinstance(r["scale"], (int, float)) or r["scale"] == 0:
            err("scale", f"{r['scale']!r} is not a non-zero number")
    if errors:
        raise RegmapError("\n".join(errors))
    return regs


def c_int(v):
    """An integer literal valid for int64_t, including INT32_MIN."""
    if v < 0:
        return f"(-{-v}LL)"
    return f"{v}LL"


def sorted_regs(regs):
    return sorted(regs, key=lambda r: (TABLE_ORDER.index(r["table"]), r["address"]))


def table_sizes(regs):
    sizes = {t: 0 for t in TABLES}
    for r in regs:
        end = r["address"] + TYPES[r["type"]][1]
        sizes[r["table"]] = max(sizes[r["table"]], end)
    return sizes


def gen_header(regs, src):
    out = [
        "/* Generated by scripts/gen_regmap.py from " + src + ". Do not edit. */",
        "#ifndef LEVELER_REGMAP_ADDR_H",
        "#define LEVELER_REGMAP_ADDR_H",
        "",
        "/* 0-based protocol addresses; 32-bit values take two registers, high word first. */",
    ]
    for r in sorted_regs(regs):
        prefix = TABLES[r["table"]][1]
        out.append(f"#define LEVELER_{prefix}_{r['name'].upper()} {r['address']}u /* {r['type']}, {r['unit'] or '-'} */")
    out.append("")
    out.append("/* One past the highest address of each table. */")
    sizes = table_sizes(regs)
    for t in TABLE_ORDER:
        out.append(f"#define LEVELER_{TABLES[t][1]}_TABLE_SIZE {sizes[t]}u")
    out.append(f"#define LEVELER_REGMAP_ENTRY_COUNT {len(regs)}u")
    for r in regs:
        if "enum" in r:
            for k, v in r["enum"].items():
                key = re.sub(r"[^A-Za-z0-9]", "_", k).upper()
                out.append(f"#define LEVELER_{TABLES[r['table']][1]}_{r['name'].upper()}_{key} {v}u")
    out += ["", "#endif /* LEVELER_REGMAP_ADDR_H */", ""]
    return "\n".join(out)


def gen_table(regs, src):
    out = [
        "/* Generated by scripts/gen_regmap.py from " + src + ". Do not edit. */",
        "#include <stddef.h>",
        '#include "leveler/regmap_desc.h"',
        '#include "leveler/regmap_addr.h"',
        "",
        "/* A bind's C field must have the width its JSON type says. */",
    ]
    width = {"bit": "1", "uint16": "2", "int32": "4", "uint32": "4"}
    for r in regs:
        prefix, field = r["bind"].split(".", 1)
        struct = BIND_STRUCTS[prefix][1]
        out.append(f"_Static_assert(sizeof(((const {struct} *)0)->{field}) == {width[r['type']]}u,"
                   f" \"{r['name']}: field {r['bind']} is not a {r['type']}\");")
    out += ["", "const leveler_reg_desc leveler_reg_table[LEVELER_REGMAP_ENTRY_COUNT] = {"]
    for r in sorted_regs(regs):
        prefix, field = r["bind"].split(".", 1)
        region, struct = BIND_STRUCTS[prefix]
        flags = []
        if "enum" in r:
            flags.append("LEVELER_REGFLAG_ENUM")
        out.append(
            f"    {{ /* {r['name']} */ .min = {c_int(r['range'][0])}, .max = {c_int(r['range'][1])},"
            f" .default_value = {c_int(r.get('default', 0))},"
            f" .offset = (uint16_t)offsetof({struct}, {field}), .address = {r['address']}u,"
            f" .table = {TABLES[r['table']][0]}, .type = {TYPES[r['type']][0]},"
            f" .access = {ACCESS[r['access']]}, .region = {region},"
            f" .flags = {' | '.join(flags) if flags else '0'}, .has_default = {1 if 'default' in r else 0} }},")
    out += ["};", ""]
    return "\n".join(out)


def md_cell(s):
    return str(s).replace("|", "\\|")


def fmt_range(r):
    lo, hi = r["range"]
    s = f"{lo}..{hi}"
    if "enum" in r:
        s += " (" + ", ".join(f"{v}={k}" for k, v in r["enum"].items()) + ")"
    return s


def gen_doc(doc, regs, src):
    out = [
        "# Register map",
        "",
        f"Generated by `scripts/gen_regmap.py` from `{src}`; do not edit by hand.",
        "Regenerate with `cmake --build <build dir> --target regmap-docs` (a unit test fails when this",
        "file and the JSON disagree).",
        "",
        f"- Addressing: {doc.get('addressing', '0-based protocol addresses')}.",
        f"- Word order: {doc.get('word_order', 'high word first')}.",
        "- Pressures are absolute pascals, heights micrometres.",
        "- A read may span several registers and unmapped gaps (gaps read 0) but may not split a",
        "  32-bit value; writes to gaps or read-only items are refused.",
        "- A write is validated whole before anything changes (each field's range, then the",
        "  settings' consistency); a refused write changes nothing and sets `last_refusal_reason`",
        "  (1 read-only, 2 out of range, 3 band order, 4 limit order, 5 calibration, 6 bad enum,",
        "  7 split 32-bit value).",
        "",
    ]
    sizes = table_sizes(regs)
    for t in TABLE_ORDER:
        rows = [r for r in sorted_regs(regs) if r["table"] == t]
        if not rows:
            continue
        out.append(f"## {TABLES[t][2]} ({TABLES[t][3]}, size {sizes[t]})")
        out.append("")
        out.append("| address | name | type | scale | unit | range | R/W | word order | default | description |")
        out.append("|---:|---|---|---|---|---|---|---|---|---|")
        for r in rows:
            words = TYPES[r["type"]][1]
            addr = f"{r['address']}" if words == 1 else f"{r['address']}-{r['address'] + 1}"
            order = "hi, lo" if words == 2 else "-"
            out.append("| " + " | ".join(md_cell(c) for c in [
                addr, f"`{r['name']}`", r["type"], r["scale"], r["unit"] or "-", fmt_range(r),
                r["access"], order, r.get("default", "-"), r["description"]]) + " |")
        out.append("")
    return "\n".join(out)


# 1-based Modbus references as HMI/SCADA tools number the tables (Modicon style).
REFERENCE_BASE = {"coil": 1, "discrete": 10001, "input": 30001, "holding": 40001}


def gen_tags(regs):
    """The tag export: one CSV row per item, for HMI/SCADA import."""
    import csv
    import io
    out = io.StringIO()
    w = csv.writer(out, lineterminator="\n")
    w.writerow(["name", "table", "address_0based", "reference_1based", "function_read", "function_write",
                "type", "registers", "word_order", "unit", "scale", "access", "range_lo", "range_hi", "description"])
    writes = {"coil": "05/15", "holding": "06/16"}
    reads = {"coil": "01", "discrete": "02", "holding": "03", "input": "04"}
    for r in sorted_regs(regs):
        words = TYPES[r["type"]][1]
        w.writerow([r["name"], r["table"], r["address"], REFERENCE_BASE[r["table"]] + r["address"],
                    reads[r["table"]], writes.get(r["table"], "") if r["access"] == "RW" else "",
                    r["type"], words, "high word first" if words == 2 else "", r["unit"], r["scale"], r["access"],
                    r["range"][0], r["range"][1], r["description"]])
    return out.getvalue()


def write_if_changed(path, text):
    if path == "-":
        sys.stdout.write(text)
        return
    try:
        with open(path, encoding="utf-8") as f:
            if f.read() == text:
                return
    except OSError:
        pass
    with open(path, "w", encoding="utf-8") as f:
        f.write(text)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("json")
    ap.add_argument("--header")
    ap.add_argument("--table")
    ap.add_argument("--doc")
    ap.add_argument("--tags", help="write the HMI/SCADA tag export (CSV) here")
    ap.add_argument("--source-name", default="firmware/regmap/registers.json",
                    help="path shown in generated files (keeps them independent of the build folder)")
    args = ap.parse_args(argv)
    try:
        doc = load(args.json)
        regs = validate(args.json, doc)
    except RegmapError as e:
        print(f"gen_regmap: error:\n{e}", file=sys.stderr)
        return 1
    if args.header:
        write_if_changed(args.header, gen_header(regs, args.source_name))
    if args.table:
        write_if_changed(args.table, gen_table(regs, args.source_name))
    if args.doc:
        write_if_changed(args.doc, gen_doc(doc, regs, args.source_name))
    if args.tags:
        write_if_changed(args.tags, gen_tags(regs))
    return 0


if __name__ == "__main__":
    sys.exit(main())

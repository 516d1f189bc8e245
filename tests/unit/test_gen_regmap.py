"""gen_regmap.py refuses broken register maps, naming the entry and the field (stdlib unittest)."""
import copy
import json
import os
import subprocess
import sys
import tempfile
import unittest

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.normpath(os.path.join(HERE, "..", ".."))
GEN = os.path.join(ROOT, "scripts", "gen_regmap.py")
with open(os.path.join(ROOT, "firmware", "regmap", "registers.json"), encoding="utf-8") as f:
    GOOD = json.load(f)


def run(doc):
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "registers.json")
        with open(path, "w", encoding="utf-8") as f:
            json.dump(doc, f, indent=1)
        p = subprocess.run([sys.executable, GEN, path, "--header", os.path.join(tmp, "a.h"),
                            "--table", os.path.join(tmp, "t.c")], capture_output=True, text=True)
        return p.returncode, p.stderr


def mutate(name, **changes):
    doc = copy.deepcopy(GOOD)
    for r in doc["registers"]:
        if r["name"] == name:
            r.update(changes)
    return doc


class Validation(unittest.TestCase):
    def assertRefused(self, doc, *words):
        rc, err = run(doc)
        self.assertEqual(rc, 1, err)
        for w in words:
            self.assertIn(w, err)

    def test_good_map_accepted(self):
        self.assertEqual(run(GOOD), (0, ""))

    def test_overlap(self):
        self.assertRefused(mutate("algorithm", address=0), "(algorithm)", "'address'", "overlaps", "'mode'")

    def test_32bit_at_odd_address(self):
        self.assertRefused(mutate("stall_min_rise_pa", address=15), "(stall_min_rise_pa)", "odd address 15")

    def test_32bit_overlapping_next(self):
        self.assertRefused(mutate("band_upper_um", address=3), "(band_upper_um)", "'address'")

    def test_default_outside_range(self):
        self.assertRefused(mutate("mode", default=5), "(mode)", "'default'", "outside range")

    def test_unknown_type_table_access_bind(self):
        self.assertRefused(mutate("mode", type="float"), "(mode)", "'type'", "unknown type")
        self.assertRefused(mutate("mode", table="eeprom"), "(mode)", "'table'", "unknown table")
        self.assertRefused(mutate("mode", access="W"), "(mode)", "'access'")
        self.assertRefused(mutate("mode", bind="nowhere.mode"), "(mode)", "'bind'", "unknown bind")

    def test_error_names_file_line(self):
        rc, err = run(mutate("mode", default=5))
        self.assertRegex(err, r"registers\.json:\d+: register #\d+ \(mode\)")


class TagExport(unittest.TestCase):
    """The HMI tag export: every item once, Modicon references (coils 1, discrete
    inputs 10001, input registers 30001, holding registers 40001 for address 0)."""

    def test_every_item_with_its_references(self):
        import csv
        import io
        p = subprocess.run([sys.executable, GEN, os.path.join(ROOT, "firmware", "regmap", "registers.json"),
                            "--tags", "-"], capture_output=True, text=True, check=True)
        rows = list(csv.DictReader(io.StringIO(p.stdout)))
        self.assertEqual(sorted(r["name"] for r in rows), sorted(r["name"] for r in GOOD["registers"]))
        first = {"coil": 1, "discrete": 10001, "input": 30001, "holding": 40001}
        for want in GOOD["registers"]:
            got = next(r for r in rows if r["name"] == want["name"])
            self.assertEqual(int(got["address_0based"]), want["address"])
            self.assertEqual(int(got["reference_1based"]), first[want["table"]] + want["address"])
            self.assertEqual(got["unit"], want["unit"])
            self.assertEqual(got["word_order"], "high word first" if want["type"] in ("int32", "uint32") else "")
            self.assertEqual(bool(got["function_write"]), want["access"] == "RW" and want["table"] in ("coil", "holding"))
        height = next(r for r in rows if r["name"] == "height_um")
        self.assertEqual((height["reference_1based"], height["registers"]), ("30001", "2"))


if __name__ == "__main__":
    unittest.main()

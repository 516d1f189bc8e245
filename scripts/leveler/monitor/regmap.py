"""The register map as leveler-monitor uses it: firmware/regmap/registers.json,
loaded and checked by the generator's own loader (scripts/gen_regmap.py), and
the two conversions a Modbus peer needs: table words -> named values (type,
word order, scale) and a named value -> the words of its write.

Nothing here names an address: every address, type, scale and enum comes
from the JSON.
"""
import os
import sys

_SCRIPTS = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
if _SCRIPTS not in sys.path:
    sys.path.insert(0, _SCRIPTS)
import gen_regmap  # noqa: E402  (scripts/gen_regmap.py, standard library only)

DEFAULT_PATH = os.path.join(os.path.dirname(_SCRIPTS), "firmware", "regmap", "registers.json")
MAX_READ_WORDS = 125     # Modbus limit of one FC 03/04 read
MAX_READ_BITS = 2000     # Modbus limit of one FC 01/02 read


class RegmapError(Exception):
    """The register map cannot be loaded or a value does not fit it."""


class RegisterMap:
    def __init__(self, path=DEFAULT_PATH):
        try:
            doc = gen_regmap.load(path)
            gen_regmap.validate(path, doc)
        except gen_regmap.RegmapError as e:
            raise RegmapError(str(e))
        self.path = path
        self.high_word_first = str(doc.get("word_order", "high word first")).startswith("high word first")
        self.regs = {r["name"]: r for r in doc["registers"]}
        self.sizes = gen_regmap.table_sizes(doc["registers"])

    def __getitem__(self, name):
        return self.regs[name]

    def words(self, name):
        return gen_regmap.TYPES[self.regs[name]["type"]][1]

    def table(self, table):
        """The items of one table in address order."""
        return sorted((r for r in self.regs.values() if r["table"] == table), key=lambda r: r["address"])

    def read_spans(self, table):
        """(address, count) reads that cover the table, none longer than Modbus
        allows, none splitting a 32-bit value."""
        limit = MAX_READ_BITS if table in gen_regmap.BIT_TABLES else MAX_READ_WORDS
        spans = []
        for r in self.table(table):
            end = r["address"] + self.words(r["name"])
            if spans and end - spans[-1][0] <= limit:
                spans[-1] = (spans[-1][0], end - spans[-1][0])
            else:
                spans.append((r["address"], end - r["address"]))
        return spans

    def decode(self, table, start, words):
        """{name: value in the register's unit} of the items inside words (read from start)."""
        out = {}
        for r in self.table(table):
            i = r["address"] - start
            n = self.words(r["name"])
            if i < 0 or i + n > len(words):
                continue
            out[r["name"]] = self._value(r, words[i:i + n])
        return out

    def _value(self, r, w):
        if r["type"] == "bit":
            raw = 1 if w[0] else 0
        elif r["type"] == "uint16":
            raw = w[0]
        else:
            hi, lo = (w[0], w[1]) if self.high_word_first else (w[1], w[0])
            raw = (hi << 16) | lo
            if r["type"] == "int32" and raw >= 1 << 31:
                raw -= 1 << 32
        return raw * r["scale"]

    def encode(self, name, value):
        """The words (one, or two in the map's word order) that write value to name;
        checks the type's width only: the firmware validates the range itself."""
        r = self.regs[name]
        raw = round(value / r["scale"])
        lo_ok, hi_ok = gen_regmap.TYPES[r["type"]][2:4]
        if not lo_ok <= raw <= hi_ok:
            raise RegmapError(f"{name}: {value} does not fit a {r['type']}")
        if self.words(name) == 1:
            return [raw]
        u = raw & 0xFFFFFFFF
        hi, lo = u >> 16, u & 0xFFFF
        return [hi, lo] if self.high_word_first else [lo, hi]

    def enum_name(self, name, value):
        """The enum's name for value, or the number when it has none."""
        for k, v in self.regs[name].get("enum", {}).items():
            if v == value:
                return k
        return str(value)

    def bit_names(self, code_register, bits):
        """Names of the set bits of a fault bit field (bit = code - 1, named by code_register's enum)."""
        return [self.enum_name(code_register, b + 1) for b in range(16) if bits >> b & 1]

    def writable(self, table="holding"):
        return [r["name"] for r in self.table(table) if r["access"] == "RW"]

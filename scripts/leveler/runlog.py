"""Read and write the leveler run log (docs/log-format.md).

One CSV format for the simulator, the rig and the diagnosis tool::

    # leveler run log, format 2
    # config: thesis-900lb
    # source: sim
    t_s,height_m,p_spring_pa,p_pipe_pa,p_acc_pa,load_n,compressor,spring_valve,vent_valve,acc_valve
    0.000000,0.39751,613633.1,613633.1,,4003.4,0,0,0,0

SI units, absolute pressures. Pressure and actuator cells may be empty where
the rig does not measure them; they read as NaN. ``t_s``, ``height_m`` and
``load_n`` are required in every row.

``read(path)`` returns a :class:`RunLog`; any problem raises
:class:`RunLogError`, whose message starts with ``file:line:`` and names the
column. ``write(path, log)`` writes atomically (temporary file + rename).
"""

from __future__ import annotations

import csv
import dataclasses
import io
import math
import os
import re
import tempfile
from typing import Dict, Optional

import numpy as np

from .cli import umask_mode

FORMAT_VERSION = 3

# THE signal tuples, in the order every layer keeps (the engine's sensed and
# actuator columns, the log's, the diagnosis's traces): one definition, here
SIGNALS = ("height_m", "p_spring_pa", "p_pipe_pa", "p_acc_pa")
ACTUATORS = ("compressor", "spring_valve", "vent_valve", "acc_valve")
PRESSURES = SIGNALS[1:]
BASE_COLUMNS = ("t_s",) + SIGNALS + ("load_n",) + ACTUATORS
# format 3: the firmware's state after the tick, and the plant's true state (simulated runs)
STATE = ("mode", "control_state", "latched_fault_bits", "sensors_valid")
TRUTH = tuple("true_" + s for s in SIGNALS)
COLUMNS = BASE_COLUMNS + STATE + TRUTH
# The header each format has; format 1 called the valves solenoid and vent.
# Older formats read with the format 3 columns they lack empty (NaN).
HEADERS = {1: BASE_COLUMNS[:7] + ("solenoid", "vent", "acc_valve"), 2: BASE_COLUMNS, 3: COLUMNS}
SUPPORTED_VERSIONS = tuple(HEADERS)
REQUIRED = ("t_s", "height_m", "load_n")          # never empty
FLAGS = ACTUATORS + ("sensors_valid",)          # 0/1 cells
INTEGERS = ("mode", "control_state", "latched_fault_bits")
SOURCES = ("sim", "rig")

_TITLE = re.compile(r"^#\s*leveler run log,\s*format\s+(\S+)\s*$")
_KEY_VALUE = re.compile(r"^#\s*([A-Za-z0-9_.\-]+)\s*:\s*(.*?)\s*$")


class RunLogError(ValueError):
    """A malformed run log; ``str()`` reads ``file:line: what is wrong``."""

    def __init__(self, path, line, message):
        self.path = str(path)
        self.line = line
        self.message = message
        where = f"{self.path}:{line}" if line is not None else self.path
        super().__init__(f"{where}: {message}")


@dataclasses.dataclass
class RunLog:
    """A run log in memory. Arrays are float64, one entry per row.

    Actuator arrays hold 0.0 / 1.0, NaN where the cell was empty; pressure
    arrays hold absolute Pa, NaN where empty.
    """
    t_s: np.ndarray
    height_m: np.ndarray
    p_spring_pa: np.ndarray
    p_pipe_pa: np.ndarray
    p_acc_pa: np.ndarray
    load_n: np.ndarray
    compressor: np.ndarray
    spring_valve: np.ndarray
    vent_valve: np.ndarray
    acc_valve: np.ndarray
    mode: Optional[np.ndarray] = None
    control_state: Optional[np.ndarray] = None
    latched_fault_bits: Optional[np.ndarray] = None
    sensors_valid: Optional[np.ndarray] = None
    true_height_m: Optional[np.ndarray] = None
    true_p_spring_pa: Optional[np.ndarray] = None
    true_p_pipe_pa: Optional[np.ndarray] = None
    true_p_acc_pa: Optional[np.ndarray] = None
    format_version: int = FORMAT_VERSION
    config: str = ""
    source: str = "sim"
    meta: Dict[str, str] = dataclasses.field(default_factory=dict)
    path: Optional[str] = None

    def __post_init__(self):
        for name in STATE + TRUTH:
            if getattr(self, name) is None:
                setattr(self, name, np.full(len(self.t_s), np.nan))

    def __len__(self):
        return len(self.t_s)

    def column(self, name):
        return getattr(self, name)

    @classmethod
    def from_arrays(cls, t_s, height_m, load_n, p_spring_pa=None, p_pipe_pa=None,
                    p_acc_pa=None, compressor=None, spring_valve=None, vent_valve=None,
                    acc_valve=None, config="", source="sim", meta=None, **extra):
        """Builds a log from arrays; missing optional columns become NaN."""
        t = np.asarray(t_s, dtype=float)
        n = len(t)

        def col(v):
            if v is None:
                return np.full(n, np.nan)
            a = np.asarray(v, dtype=float)
            if a.shape == ():
                a = np.full(n, float(a))
            if a.shape != (n,):
                raise ValueError(f"column has {a.shape} entries, t_s has {n}")
            return a
        unknown = set(extra) - set(STATE + TRUTH)
        if unknown:
            raise TypeError("unknown run-log column(s): " + ", ".join(sorted(unknown)))
        return cls(t, col(height_m), col(p_spring_pa), col(p_pipe_pa), col(p_acc_pa),
                   col(load_n), col(compressor), col(spring_valve), col(vent_valve), col(acc_valve),
                   **{name: col(extra.get(name)) for name in STATE + TRUTH},
                   format_version=FORMAT_VERSION, config=config, source=source, meta=dict(meta or {}))


# --- units detection -----------------------------------------------------------
# Plausible ranges for this product (a rolling-lobe air spring, 0.1..1 MPa).
HEIGHT_RANGE_M = (0.05, 2.0)
PRESSURE_RANGE_PA = (5.0e4, 5.0e6)       # absolute; below ~0.5 atm is not this system
LOAD_RANGE_N = (0.0, 1.0e5)


def _range_text(values):
    return f"{np.nanmin(values):.6g}..{np.nanmax(values):.6g}"


def check_units(column, values):
    """Returns None if ``values`` look like the SI unit of ``column``, else a
    sentence saying what unit they look like. Uses the median of the finite
    values, so a few outliers do not decide."""
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return None
    med = float(np.median(v))
    rng = _range_text(v)
    if column == "height_m":
        lo, hi = HEIGHT_RANGE_M
        if lo <= med <= hi:
            return None
        if 2.0 < med <= 80.0:
            return (f"values {rng} look like inches, not metres "
                    f"(expected {lo}..{hi} m; multiply inches by 0.0254)")
        if 50.0 < med <= 2000.0:
            return (f"values {rng} look like millimetres, not metres "
                    f"(expected {lo}..{hi} m; divide mm by 1000)")
        if 5.0 <= med * 100 <= 200.0:
            return f"values {rng} look like centimetres or decimetres, not metres"
        return f"values {rng} are not plausible heights in metres (expected {lo}..{hi} m)"
    if column in PRESSURES:
        lo, hi = PRESSURE_RANGE_PA
        vmin = float(np.min(v))
        if lo <= med <= hi and vmin >= lo:
            return None
        if med < 350.0:
            if vmin < 14.0:
                return (f"values {rng} look like gauge psi (psig), not absolute Pa "
                        f"(Pa = (psig + 14.7) * 6894.76)")
            return (f"values {rng} look like absolute psi (psia), not Pa "
                    f"(Pa = psia * 6894.76)")
        if med < 5000.0:
            if vmin < 90.0:
                return (f"values {rng} look like gauge kPa, not absolute Pa "
                        f"(Pa = kPa * 1000 + 101325)")
            return f"values {rng} look like absolute kPa, not Pa (Pa = kPa * 1000)"
        if med <= hi:
            return (f"values {rng} look like gauge Pa (below {lo:.0f} Pa absolute); "
                    f"the log holds absolute pressures (add ambient, about 101325 Pa)")
        return f"values {rng} are too large for pressures in Pa (expected {lo:.0f}..{hi:.0f})"
    if column == "load_n":
        lo, hi = LOAD_RANGE_N
        if lo <= med <= hi and float(np.min(v)) >= lo:
            return None
        return f"values {rng} are not plausible loads in N (expected {lo:.0f}..{hi:.0f})"
    return None


# --- reading -------------------------------------------------------------------

def _parse_number(text, path, line, column):
    try:
        value = float(text)
    except ValueError:
        raise RunLogError(path, line, f"column {column}: '{text}' is not a number") from None
    if not math.isfinite(value):
        raise RunLogError(path, line, f"column {column}: '{text}' is not a finite number "
                                      f"(leave the cell empty if not measured)")
    return value


def read(path, check_unit=True):
    """Reads a run log. Raises RunLogError (file:line: message) if malformed,
    including when a column's values look like the wrong unit."""
    path = os.fspath(path)
    try:
        with open(path, "r", encoding="utf-8", newline="") as f:
            text = f.read()
    except OSError as e:
        raise RunLogError(path, None, f"cannot read: {e.strerror}") from None
    except UnicodeDecodeError as e:
        raise RunLogError(path, None, f"not UTF-8 text ({e.reason})") from None
    return parse(text, path=path, check_unit=check_unit)


def _version(text, path, lineno):
    """The format number of a title or ``# format:`` line; RunLogError if unknown."""
    try:
        version = int(text)
    except ValueError:
        raise RunLogError(path, lineno, f"format version '{text}' is not a number") from None
    if version not in SUPPORTED_VERSIONS:
        raise RunLogError(path, lineno, f"unknown format version {version} "
                                        f"(this reader knows {', '.join(map(str, SUPPORTED_VERSIONS))})")
    return version


def parse(text, path="<string>", check_unit=True):
    """Parses run-log text; ``path`` is only used in error messages."""
    lines = text.splitlines()
    meta: Dict[str, str] = {}
    version = None
    lineno = 0
    # Comment block: title line with the format version, then "# key: value".
    while lineno < len(lines) and lines[lineno].startswith("#"):
        raw = lines[lineno]
        lineno += 1
        m = _TITLE.match(raw)
        if m:
            version = _version(m.group(1), path, lineno)
            continue
        m = _KEY_VALUE.match(raw)
        if m:
            key, value = m.group(1).lower(), m.group(2)
            if key == "format":
                version = _version(value, path, lineno)
            else:
                meta[key] = value
        # any other comment line is free text
    if version is None:
        raise RunLogError(path, 1, f"no format line ('# leveler run log, format {FORMAT_VERSION}') "
                                   "in the comment block at the top")
    expected = HEADERS[version]
    if lineno >= len(lines):
        raise RunLogError(path, lineno + 1, "missing header line " + ",".join(expected))
    header_line = lineno + 1
    header = [h.strip() for h in lines[lineno].split(",")]
    lineno += 1
    missing = [c for c in expected if c not in header]
    extra = [c for c in header if c not in expected]
    if missing or extra:
        parts = []
        if missing:
            parts.append("missing column(s) " + ", ".join(missing))
        if extra:
            parts.append("unknown column(s) " + ", ".join(repr(c) for c in extra))
        raise RunLogError(path, header_line, "header: " + "; ".join(parts)
                          + "; expected " + ",".join(expected))
    if len(set(header)) != len(header):
        raise RunLogError(path, header_line, "header: a column appears twice")
    if header != list(expected):
        raise RunLogError(path, header_line, "header: columns out of order; expected "
                          + ",".join(expected))

    source = meta.get("source", "")
    if source and source not in SOURCES:
        raise RunLogError(path, None, f"source '{source}' is neither 'sim' nor 'rig'")

    fast = _rows_at_once(lines, lineno, len(expected))
    data, row_lines = fast if fast is not None else _rows_one_by_one(lines, lineno, expected, path)
    if len(data) == 0:
        raise RunLogError(path, header_line + 1, "no data rows after the header")

    if check_unit:
        for j, name in enumerate(COLUMNS):
            if name in ("height_m", "load_n") or name in PRESSURES:
                problem = check_units(name, data[:, j])
                if problem:
                    finite = np.flatnonzero(np.isfinite(data[:, j]))
                    raise RunLogError(path, int(row_lines[finite[0]]), f"column {name}: {problem}")

    cols = {name: data[:, j].copy() for j, name in enumerate(COLUMNS)}
    return RunLog(**cols, format_version=version, config=meta.pop("config", ""),
                  source=meta.pop("source", "") or "sim", meta=meta, path=path)


_NOT_PLAIN = re.compile(r"[^0-9eE+\-.,\n ]")


def _rows_at_once(lines, lineno, ncol):
    """The data rows of a plainly well-formed log in one pass of numpy's C reader
    (a 5,501-row log in 14 ms, not the cell-by-cell 40): (data, line numbers),
    or None whenever any row is not plain (a character other than
    digits, sign, point, exponent and commas; a wrong cell count; a flag not 0/1;
    time not increasing ...): then _rows_one_by_one reads it and names the first
    fault. Formats 1 and 2 (fewer columns) always go one by one."""
    if ncol != len(COLUMNS):
        return None
    body = [(i, ln) for i, ln in enumerate(lines[lineno:], lineno + 1) if ln.strip()]
    text = "\n".join(ln for _, ln in body)
    if not body or _NOT_PLAIN.search(text):
        return None
    # empty cells (not measured) as NaN: no "nan" can come from the file itself
    text = text.replace(",,", ",nan,").replace(",,", ",nan,").replace(",\n", ",nan\n")
    text = text + "nan" if text.endswith(",") else text
    try:
        data = np.loadtxt(io.StringIO(text), delimiter=",", ndmin=2, dtype=np.float64)
    except ValueError:
        return None
    if data.shape != (len(body), ncol) or not _well_formed(data, np.isnan(data)):
        return None
    return data, np.array([i for i, _ in body], dtype=np.int64)


def _well_formed(data, empty):
    """What _rows_one_by_one checks, for the whole table at once."""
    col = {name: j for j, name in enumerate(COLUMNS)}
    if not np.isfinite(data[~empty]).all() or any(empty[:, col[c]].any() for c in REQUIRED):
        return False
    for name in FLAGS:
        v = data[:, col[name]]
        if not np.all(np.isnan(v) | (v == 0.0) | (v == 1.0)):
            return False
    for name in INTEGERS:
        v = data[:, col[name]]
        if not np.all(np.isnan(v) | ((v >= 0) & (v == np.floor(v)))):
            return False
    return bool(np.all(np.diff(data[:, 0]) > 0))


def _rows_one_by_one(lines, lineno, expected, path):
    """The data rows cell by cell, with the file:line: column message of the first fault."""
    ncol = len(expected)
    data = np.full((max(len(lines) - lineno, 0), len(COLUMNS)), np.nan)
    row_lines = np.zeros(len(data), dtype=np.int64)
    nrows = 0
    reader = csv.reader(lines[lineno:])
    for offset, cells in enumerate(reader):
        line = lineno + offset + 1
        if not cells or (len(cells) == 1 and cells[0].strip() == ""):
            continue            # blank line (e.g. trailing)
        if cells[0].startswith("#"):
            raise RunLogError(path, line, "comment line after the header")
        if len(cells) != ncol:
            raise RunLogError(path, line, f"{len(cells)} cells, expected {ncol} ("
                              + ("missing cells" if len(cells) < ncol else "extra cells") + ")")
        row = data[nrows]
        for j, (name, cell) in enumerate(zip(expected, cells)):
            cell = cell.strip()
            if cell == "":
                if name in REQUIRED:
                    raise RunLogError(path, line, f"column {name}: empty cell (required)")
                continue
            value = _parse_number(cell, path, line, name)
            if COLUMNS[j] in FLAGS and value not in (0.0, 1.0):
                what = "actuator state" if COLUMNS[j] in ACTUATORS else "state"
                raise RunLogError(path, line, f"column {name}: {what} '{cell}' is not 0 or 1")
            if COLUMNS[j] in INTEGERS and not (value >= 0 and value == int(value)):
                raise RunLogError(path, line, f"column {name}: '{cell}' is not a whole number >= 0")
            row[j] = value
        if nrows > 0 and not row[0] > data[nrows - 1, 0]:
            raise RunLogError(path, line, f"column t_s: time {cells[0].strip()} does not increase "
                              f"(previous row {data[nrows - 1, 0]:.9g})")
        row_lines[nrows] = line
        nrows += 1
    return data[:nrows], row_lines[:nrows]


# --- writing -------------------------------------------------------------------

def _fmt(value):
    return "" if not math.isfinite(value) else repr(float(value))


def _fmt_flag(value):
    return "" if not math.isfinite(value) else ("1" if value else "0")


def format_text(log: RunLog):
    """The run log as text (the exact file ``write`` produces)."""
    out = io.StringIO()
    out.write(f"# leveler run log, format {FORMAT_VERSION}\n")
    out.write(f"# config: {log.config}\n")
    out.write(f"# source: {log.source}\n")
    for key, value in log.meta.items():
        if key in ("config", "source", "format"):
            continue
        out.write(f"# {key}: {value}\n")
    out.write(",".join(COLUMNS) + "\n")
    cols = [log.column(c) for c in COLUMNS]
    n = len(log.t_s)
    for c, name in zip(cols, COLUMNS):
        if len(c) != n:
            raise ValueError(f"column {name} has {len(c)} entries, t_s has {n}")
    for i in range(n):
        cells = []
        for name, c in zip(COLUMNS, cols):
            if name in FLAGS:
                cells.append(_fmt_flag(c[i]))
            elif name in INTEGERS:
                cells.append("" if not math.isfinite(c[i]) else str(int(c[i])))
            else:
                cells.append(_fmt(c[i]))
        out.write(",".join(cells) + "\n")
    return out.getvalue()


def write_text_atomic(path, text, mode="w"):
    """Writes ``text`` to ``path`` via a temporary file in the same folder and a
    rename, so a reader never sees half a file. ``mode`` "wb" for bytes."""
    path = os.fspath(path)
    folder = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(prefix="." + os.path.basename(path) + ".", suffix=".tmp", dir=folder)
    try:
        os.fchmod(fd, umask_mode(0o666))   # mkstemp makes 0600; the file gets what open() would give
        with os.fdopen(fd, mode, **({} if "b" in mode else {"encoding": "utf-8", "newline": ""})) as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


def write(path, log: RunLog):
    """Writes ``log`` to ``path`` atomically."""
    write_text_atomic(path, format_text(log))

"""Read and check run logs (docs/log-format.md) for the diagnosis.

A run log is CSV with '#' comment lines ("# config: NAME", "# source: sim|rig")
and the header
    t_s,height_m,p_spring_pa,p_pipe_pa,p_acc_pa,load_n,compressor,solenoid,vent,acc_valve
SI units, absolute pressures; empty cell = not measured. Every problem is
reported as DiagnoseInputError naming file, line and field.
"""
import csv
from dataclasses import dataclass, field

import numpy as np

from .errors import DiagnoseInputError, where

REQUIRED = ("t_s", "height_m", "p_spring_pa", "load_n")
OPTIONAL = ("p_pipe_pa", "p_acc_pa", "compressor", "solenoid", "vent", "acc_valve")
COMMANDS = ("compressor", "solenoid", "vent", "acc_valve")
SIGNALS = ("height_m", "p_spring_pa", "p_pipe_pa", "p_acc_pa")

# Plausible SI ranges; a value outside them by orders of magnitude is a unit mistake.
# (field, lo, hi, hint for what the unit probably is)
RANGES = {
    "height_m": (0.05, 1.5, [(1.0, 60.0, "inches"), (50.0, 1500.0, "millimetres")]),
    "p_spring_pa": (2.0e4, 3.0e6, [(0.0, 20.0, "bar or MPa"), (20.0, 400.0, "psi or kPa")]),
    "p_pipe_pa": (2.0e4, 3.0e6, [(0.0, 20.0, "bar or MPa"), (20.0, 400.0, "psi or kPa")]),
    "p_acc_pa": (2.0e4, 3.0e6, [(0.0, 20.0, "bar or MPa"), (20.0, 400.0, "psi or kPa")]),
    "load_n": (0.0, 1.0e5, [(1.0e5, 1.0e9, "a wrong unit (mN?)")]),
}


@dataclass
class Run:
    """One run: signals sampled at t_s (SI). Missing signal = all-NaN array."""
    path: str
    t_s: np.ndarray
    signals: dict                      # name -> array (NaN where not measured)
    load_n: np.ndarray
    commands: dict = field(default_factory=dict)   # name -> int array; empty if not logged
    config: str = ""
    source: str = ""

    @property
    def name(self):
        import os
        return os.path.basename(self.path)

    @property
    def has_commands(self):
        return all(c in self.commands for c in ("compressor", "solenoid", "vent"))

    def measured(self, signal):
        a = self.signals.get(signal)
        return a is not None and np.isfinite(a).mean() > 0.5


def _parse_float(text, path, line, name):
    if text == "" or text.lower() == "nan":
        return np.nan
    try:
        return float(text)
    except ValueError:
        raise DiagnoseInputError(f"{where(path, line, name)}: not a number: {text!r}") from None


def load_run(path):
    """Read and check one run log. Raises DiagnoseInputError."""
    try:
        fh = open(path, newline="")
    except OSError as e:
        raise DiagnoseInputError(f"{path}: cannot read run log: {e.strerror}") from None
    meta = {}
    header = None
    header_line = 0
    rows = []
    with fh:
        for lineno, raw in enumerate(fh, start=1):
            line = raw.strip()
            if not line:
                continue
            if line.startswith("#"):
                body = line[1:].strip()
                if ":" in body:
                    k, v = body.split(":", 1)
                    meta[k.strip()] = v.strip()
                continue
            cells = next(csv.reader([line]))
            if header is None:
                header = [c.strip() for c in cells]
                header_line = lineno
                missing = [c for c in REQUIRED if c not in header]
                if missing:
                    raise DiagnoseInputError(
                        f"{where(path, lineno)}: missing column(s) {', '.join(missing)} "
                        f"(header has: {', '.join(header)}; see docs/log-format.md)")
                continue
            if len(cells) != len(header):
                raise DiagnoseInputError(
                    f"{where(path, lineno)}: {len(cells)} cells, header has {len(header)}")
            rows.append((lineno, cells))
    if header is None:
        raise DiagnoseInputError(f"{path}: no header line (expected t_s,height_m,...)")
    if len(rows) < 10:
        raise DiagnoseInputError(f"{where(path, header_line)}: only {len(rows)} data rows")

    cols = {}
    for name in header:
        if name not in REQUIRED + OPTIONAL:
            continue
        j = header.index(name)
        cols[name] = np.array([_parse_float(cells[j].strip(), path, ln, name) for ln, cells in rows])
    lines = np.array([ln for ln, _ in rows])

    t = cols["t_s"]
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        raise DiagnoseInputError(f"{where(path, lines[bad[0]], 't_s')}: time is empty")
    dt = np.diff(t)
    bad = np.flatnonzero(dt <= 0)
    if bad.size:
        k = bad[0] + 1
        raise DiagnoseInputError(
            f"{where(path, lines[k], 't_s')}: time not increasing ({t[k - 1]:g} then {t[k]:g})")
    for name in ("height_m", "p_spring_pa", "load_n"):
        bad = np.flatnonzero(~np.isfinite(cols[name]))
        if bad.size > 0.5 * len(t):
            raise DiagnoseInputError(f"{where(path, lines[bad[0]], name)}: mostly empty")
    for name, (lo, hi, hints) in RANGES.items():
        if name not in cols:
            continue
        v = cols[name]
        fin = v[np.isfinite(v)]
        if fin.size == 0:
            continue
        med = float(np.median(fin))
        if not (lo <= med <= hi):
            hint = next((h for a, b, h in hints if a <= abs(med) <= b), None)
            k = int(np.flatnonzero(np.isfinite(v))[0])
            msg = (f"{where(path, lines[k], name)}: typical value {med:g} is outside the "
                   f"plausible SI range {lo:g}..{hi:g}")
            if hint:
                msg += f"; it looks like {hint} (the log must be SI, pressures absolute Pa)"
            raise DiagnoseInputError(msg)

    commands = {}
    for c in COMMANDS:
        if c in cols and np.isfinite(cols[c]).all():
            v = cols[c]
            bad = np.flatnonzero((v != 0) & (v != 1))
            if bad.size:
                raise DiagnoseInputError(f"{where(path, lines[bad[0]], c)}: must be 0 or 1, got {v[bad[0]]:g}")
            commands[c] = v.astype(np.int32)
    nan = np.full(len(t), np.nan)
    signals = {s: cols.get(s, nan.copy()) for s in SIGNALS}
    return Run(path=str(path), t_s=t, signals=signals, load_n=cols["load_n"],
               commands=commands, config=meta.get("config", ""), source=meta.get("source", ""))


def write_run(path, t_s, signals, load_n, commands=None, config="", source="sim"):
    """Write a run log in docs/log-format.md (used by the blind test)."""
    commands = commands or {}
    cols = ["t_s", "height_m", "p_spring_pa", "p_pipe_pa", "p_acc_pa", "load_n",
            "compressor", "solenoid", "vent", "acc_valve"]
    with open(path, "w") as fh:
        fh.write("# leveler run log, format 1\n")
        fh.write(f"# config: {config}\n# source: {source}\n")
        fh.write(",".join(cols) + "\n")
        n = len(t_s)
        def fmt(v):
            return "" if not np.isfinite(v) else f"{v:.6g}"
        for i in range(n):
            cells = [f"{t_s[i]:.3f}", f"{signals['height_m'][i]:.7f}"]
            for s in ("p_spring_pa", "p_pipe_pa", "p_acc_pa"):
                a = signals.get(s)
                cells.append("" if a is None else fmt(a[i]))
            cells.append(f"{load_n[i]:.3f}")
            for c in ("compressor", "solenoid", "vent", "acc_valve"):
                a = commands.get(c)
                cells.append("" if a is None else str(int(a[i])))
            fh.write(",".join(cells) + "\n")

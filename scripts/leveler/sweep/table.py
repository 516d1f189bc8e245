"""The result table of a sweep: one row per point.

``OUT/sweep.csv`` is written as the points finish: one whole line per point,
flushed and synced, so a sweep that is interrupted (Ctrl-C, a lost machine)
leaves every finished point on disk and nothing else (a half line from a
crash is cut off when the table is opened again). A sweep started again with
the same study reads it and skips the points it holds; a point already in the
table is never appended again. At the end the table is written whole, in the
study's point order, as ``sweep.csv`` and ``sweep.parquet`` (each through a
temporary file and a rename).

Columns: point, point_id, config, scenario, algorithm, the varied keys
(``section.key``), config_hash (the resolved config's sha256, 16 hex
digits), version (the leveler-sim that ran it), error (a config the loader
refused), then the figures (SI; empty where not defined).
"""
from __future__ import annotations

import csv
import io
import os

from .. import runlog
from . import figures

CSV_NAME, PARQUET_NAME = "sweep.csv", "sweep.parquet"


class TableError(ValueError):
    """The output folder holds a table this sweep cannot continue."""


def columns(study):
    """(name, kind) of every column for a study; kind is int, float or str."""
    cols = [("point", "int"), ("point_id", "str"), ("config", "str"), ("scenario", "str"), ("algorithm", "int")]
    for key, values in study.vary:
        kind = "str" if any(isinstance(v, str) for v in values) else \
               "int" if all(isinstance(v, int) for v in values) else "float"
        cols.append((key, kind))
    cols += [("config_hash", "str"), ("version", "str"), ("error", "str")]
    return cols + [(f, "int" if f in figures.INTEGER else "float") for f in study.figures]


def _cell(value, kind):
    if value is None:
        return ""
    return repr(float(value)) if kind == "float" else str(int(value)) if kind == "int" else str(value)


def _parse(cell, kind):
    if cell == "":
        return None
    return float(cell) if kind == "float" else int(cell) if kind == "int" else cell


class Table:
    def __init__(self, out_dir, cols, study_name=""):
        self.out_dir, self.cols, self.study_name = out_dir, cols, study_name
        self.csv_path = os.path.join(out_dir, CSV_NAME)
        self.parquet_path = os.path.join(out_dir, PARQUET_NAME)
        self.rows = {}                       # point_id -> row

    def open(self):
        """Reads the rows already in sweep.csv (creating it with its header if
        absent) and cuts off a half-written last line. Returns the done point_ids."""
        os.makedirs(self.out_dir, exist_ok=True)
        header = [name for name, _ in self.cols]
        if not os.path.exists(self.csv_path):
            with open(self.csv_path, "w", encoding="utf-8", newline="") as fh:
                fh.write(",".join(header) + "\n")
            return set()
        with open(self.csv_path, "rb+") as fh:
            data = fh.read()
            whole = data[:data.rfind(b"\n") + 1]
            if len(whole) != len(data):
                fh.truncate(len(whole))
        lines = list(csv.reader(io.StringIO(whole.decode("utf-8"))))
        if not lines or lines[0] != header:
            raise TableError(f"{self.csv_path}: its columns are not this study's (another study's output?)")
        for cells in lines[1:]:
            row = {name: _parse(c, kind) for (name, kind), c in zip(self.cols, cells)}
            self.rows[row["point_id"]] = row
        return set(self.rows)

    def append(self, *rows):
        """Adds finished points: whole lines, one write, synced. A point already
        there is not written again. Returns how many were added."""
        new = {}
        for row in rows:
            if row["point_id"] not in self.rows:
                new[row["point_id"]] = row
        if not new:
            return 0
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        for row in new.values():
            w.writerow([_cell(row.get(n), k) for n, k in self.cols])
        self.rows.update(new)       # first: an interrupt during the write leaves them to finish()
        with open(self.csv_path, "a", encoding="utf-8", newline="") as fh:
            fh.write(buf.getvalue())
            fh.flush()
            os.fsync(fh.fileno())
        return len(new)

    def sorted_rows(self):
        return sorted(self.rows.values(), key=lambda r: r["point"])

    def finish(self):
        """The whole table in point order: sweep.csv and sweep.parquet."""
        rows = self.sorted_rows()
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow([name for name, _ in self.cols])
        for row in rows:
            w.writerow([_cell(row.get(n), k) for n, k in self.cols])
        runlog.write_text_atomic(self.csv_path, buf.getvalue())
        import pyarrow as pa            # only here: leveler-sweep --help works without the [sweep] extra
        import pyarrow.parquet as pq
        types = {"int": pa.int64(), "float": pa.float64(), "str": pa.string()}
        schema = pa.schema([(n, types[k]) for n, k in self.cols], metadata={"study": self.study_name})
        table = pa.table({n: [r.get(n) for r in rows] for n, _ in self.cols}, schema=schema)
        sink = pa.BufferOutputStream()
        pq.write_table(table, sink)
        runlog.write_text_atomic(self.parquet_path, sink.getvalue().to_pybytes(), "wb")
        return len(rows)

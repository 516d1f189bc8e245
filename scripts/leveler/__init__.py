"""leveler analysis package: run logs, event figures, thesis numbers, plots.

Modules
-------
runlog   read / write the run-log CSV (docs/log-format.md), with unit checks
thesis   published numbers of the thesis (SI) and unit helpers
events   event figures of a load step and a load removal (docs/events.md)
config   the simulator config as its C loader resolves it (leveler.engine, the C engine's binding)
engine   the C engine's one binding: libleveler_diag.so found once, its ABI checked once
plot     the report figure (matplotlib, Agg)
report   command line: python -m leveler.report --log run.csv ...
cli      the command style every Python program shares (argparse, --version, exit codes)
monitor  leveler-monitor: a live page of a rig or board over Modbus (docs/monitor.md)
paths    where the project's files are: inside the installed package, else the checkout

Everything inside is SI with absolute pressures; thesis units (in, psia, lb)
appear only where results are set beside the thesis.
"""

import os as _os


def _read_version():
    """The top-level VERSION file of the checkout (the one source; CMake reads
    it too, and the wheel's metadata is made from it), else the installed
    package's metadata."""
    from .paths import ROOT
    if ROOT is not None:
        with open(_os.path.join(ROOT, "VERSION"), encoding="utf-8") as fh:
            return fh.readline().strip()
    from importlib import metadata
    try:
        return metadata.version("leveler")
    except metadata.PackageNotFoundError:
        return "unknown"


__version__ = _read_version()

__all__ = ["runlog", "thesis", "events", "config", "plot", "report", "cli", "__version__"]

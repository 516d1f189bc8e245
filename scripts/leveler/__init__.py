"""leveler analysis package: run logs, event figures, thesis numbers, plots.

Modules
-------
runlog   read / write the run-log CSV (docs/log-format.md), with unit checks
thesis   published numbers of the thesis (SI) and unit helpers
events   event figures of a load step and a load removal (docs/events.md)
config   the simulator config as its C loader resolves it (leveler-sim --dump-config)
plot     the report figure (matplotlib, Agg)
report   command line: python -m leveler.report --log run.csv ...

Everything inside is SI with absolute pressures; thesis units (in, psia, lb)
appear only where results are set beside the thesis.
"""

__all__ = ["runlog", "thesis", "events", "config", "plot", "report"]

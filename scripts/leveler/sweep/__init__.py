"""leveler-sweep: design studies over the simulator's config keys, run on Dask
(docs/sweep.md).

Modules
-------
study    the study file (TOML): base configs, keys to vary, algorithms, scenarios, figures -> points
point    one point: its generated INI (``include`` of the base + the changed keys), run with
         leveler-sim, measured; the function a Dask worker runs
figures  the control figures of a run log beside the event figures (leveler.events)
table    the result table: one row per point, appended as points finish (CSV), resumed, and
         written whole at the end (CSV and Parquet)
engine   runs the points: on dask.distributed (a LocalCluster or --scheduler), or serially
plots    heat maps over two swept keys, lines over one
cli      the command line (leveler-sweep)
bench    throughput of a sweep and of leveler-sim alone (make bench)
"""

"""Sim-to-real gap diagnosis for the leveler plant (docs/diagnosis.md).

where the gap lies (phases x signals), which unmodelled effect closes it
(candidate effects fitted on calibration runs, scored on held-out runs),
and by how much (before/after, held-out only).
"""
import os as _os

# The diagnosis runs its own processes, one per core; the small least-squares
# solves gain nothing from BLAS threads, which otherwise spin beside them
# (measured: 8 % of a diagnosis's CPU in blas_thread_server). Before numpy loads.
_os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

"""Sim-to-real gap diagnosis for the leveler plant (docs/diagnosis.md).

where the gap lies (phases x signals), which unmodelled effect closes it
(candidate effects fitted on calibration runs, scored on held-out runs),
and by how much (before/after, held-out only).
"""

"""What the diagnosis's steps ask of its evidence, and the bar a candidate must clear.

The evidence is run logs (evidence_runs.RunLogs) or published figures
(evidence_figures.PublishedFigures); pipeline.py runs the same steps on either
and asks the strategy only where the two differ."""
from . import gap

# A candidate must shrink the held-out gap by at least this much to be named;
# otherwise the answer is `none` (noise and parameter drift stay below it).
THRESHOLD_PCT = 15.0

# Traces: a named effect must beat the sensitivity floor by this many points.
FLOOR_MARGIN_PTS = 10.0

# Perturbations far below the published resolution (0.01 in, 1 psi): 10-40 um of
# height and 50-200 Pa of pressure reading. The shrink they give by chance is
# what an on-off loop's event figures move by for no physical reason.
JITTERS = [(h, p) for h in (-40e-6, -10e-6, 10e-6, 40e-6) for p in (-200.0, 50.0)]


def sensitivity_floor(problem, nominal_gap, jitters=JITTERS):
    """Largest held-out shrink a physically meaningless jitter achieves."""
    best = 0.0
    for h, p in jitters:
        g = problem.gap("sensor_lag", {"h_offset_m": h, "p_offset_pa": p})
        best = max(best, gap.shrink(nominal_gap, g))
    return best


class Evidence:
    """One kind of evidence: the steps' questions whose answers depend on it."""

    noun = ""                       # what the held-out evidence is called in progress lines
    fits_pairs = False              # pairs fitted on top of the leader (pairs.py)
    designs_experiments = False     # look-alikes tested, separating experiments proposed

    def where(self, problem, runs):
        """The `where` table: the nominal model's gap, ranked places first."""
        raise NotImplementedError

    def where_line(self, place):
        """One ranked place of the gap, as a progress line."""
        raise NotImplementedError

    def threshold(self, hold_problem, nominal_hold_gap):
        """(sensitivity floor, the shrink an explanation must reach on the held-out evidence)."""
        raise NotImplementedError

    def signatures(self, holdout, hold_problem, ranking):
        """Adds each ranked candidate's residual signature, where the evidence has one."""

    def noise_gap(self, holdout):
        """The gap a perfect model would leave: the evidence's own noise."""
        return 0.0

    def resolution_s(self, runs):
        """The shortest time the evidence resolves (s); 0: no limit it knows of."""
        return 0.0

    def unexplained(self, hold_problem, holdout, ranking, kept, cal_gap, noise, threshold, progress):
        """What no candidate explains (confidence.unexplained), or None."""
        return None

    def before_after(self, problem, runs, nominal, augmented):
        """Held-out gaps overall, per phase and per event, nominal vs augmented."""
        raise NotImplementedError

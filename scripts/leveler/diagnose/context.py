"""What the diagnosis's steps hand each other (pipeline.py): the question, the model
the candidates are judged against, and the verdict."""
from dataclasses import dataclass
from typing import Any, Callable, Optional

from . import pairs


@dataclass
class Ask:
    """What the diagnosis was asked; the same through every step."""
    spec: Optional[str]       # the simulator as 'module:factory' (model.make_simulator), for the fitting workers
    sim: Any
    config: str               # the config as given
    mode: str
    candidates: list
    jobs: Optional[int]
    progress: Callable
    fit_opts: Optional[dict]
    design_pair: Optional[list]
    resolution_s: float = 0.0  # the logs' finest median sample interval (runs.sample_interval)


@dataclass
class Basis:
    """The model the candidates are judged against: the config as given, or on the
    calibration path the calibrated one (calib and holdout then run on it)."""
    calib: list
    holdout: list
    gaps: tuple               # its nominal (calibration, held-out) gap
    ranking: list             # the candidates, best held-out shrink first
    fits: dict
    work: Any                 # the config pairs are fitted on
    cal_problem: Any
    hold_problem: Any
    floor: float              # sensitivity floor of the held-out evidence, %
    threshold: float          # the shrink an explanation must reach, %
    calibrated: bool = False
    u_top: Any = None         # the calibration path: the leading joint fit's vector


@dataclass
class Verdict:
    """Which effect(s) are named, and what is left unexplained."""
    named: bool
    named_single: bool        # the leader alone clears the threshold and the noise gate
    pair_list: list
    kept: Optional[dict]      # the pair kept on top of the leader (pairs.py), or None
    second: Optional[dict]
    finding: Optional[dict]   # what no candidate explains (confidence.unexplained)
    winner: str
    effects: list

    def top(self, ranking):
        """The named entry (the kept pair, else the leader), or None."""
        return (self.kept or ranking[0]) if self.named else None

    def explains(self, ranking):
        """The entry the named verdict's held-out gap stands on, or None: the kept pair,
        else a pair whose second is not told apart (pairs.explaining: the leader is named
        alone, a second effect is there), else the leader."""
        return (pairs.explaining(self.pair_list, self.kept) or ranking[0]) if self.named else None

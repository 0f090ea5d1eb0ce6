"""The board interfaces the experiment loops talk to (SPEC sections 9 and 12).

The controller board (the robot's AND-OR array), the evaluator board (the world-model RAM and an
array to evaluate with) and the learning board (the GA and its lanes on one chip) as
``typing.Protocol`` classes, with the values they return. Every backend implements them; the
loops (``cosim.online``) see nothing else. Imports only ``base`` and NumPy.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from base.errors import UserError


@dataclass(frozen=True)
class EvalCounts:
    """What the evaluator returns for a population: arrays of shape (P,)."""

    crashes: np.ndarray
    loops: np.ndarray
    distance: np.ndarray
    cycles: int = 0  # clock cycles the hardware spent (0 for the reference backend)
    fails: np.ndarray | None = None  # the failure-rate count F (ga.fail_rates); None: zeros

    def __post_init__(self):
        if self.fails is None:
            object.__setattr__(self, "fails", np.zeros(np.shape(self.crashes), dtype=np.int64))


class ControllerBoard(Protocol):
    """The robot's board: holds one controller and maps sensor bits to a motion."""

    cycles: int

    def load(self, rows: np.ndarray) -> None:
        """Write the 50 row words to the shadow configuration, then commit them atomically."""

    def set_reflex(self, enabled: bool) -> None: ...

    def motion(self, state: int) -> int:
        """The motion for world state ``state`` (reflex included when enabled)."""


class EvaluatorBoard(Protocol):
    """The second board: a world-model RAM, a state set, and an AND-OR array to evaluate with."""

    cycles: int

    def observe(self, state: int, motion: int, next_state: int, crashed: bool) -> None:
        """Apply one observed transition (SPEC section 7 update rule) to the board's model."""

    def evaluate(self, population: np.ndarray) -> EvalCounts:
        """(crashes, loops, distance, fails) of every controller of ``population`` (P, 50)."""

    def write_rates(self, changes) -> None:
        """Write failure-rate codes (``ga.fail_rates``): (state, motion, code) triples. A fresh
        or cleared board holds ``PRIOR_CODE`` for every pair."""



class BoardMismatch(AssertionError):
    """A board (HDL, or behind the link) disagreed with the reference model."""


class BackendUnavailable(UserError, RuntimeError):
    """A board backend that is named in SPEC section 9 but not installed in this checkout yet."""



@dataclass(frozen=True)
class LearnResult:
    """What ``LearningBoard.learn`` returns: the controller to download and its counts."""

    rows: np.ndarray  # (50,) the download
    crashes: int
    loops: int
    distance: int
    cycles: int  # the engine's clock cycles for this learn (its exact count on every backend)
    escaped: bool = False  # the download is the escape child (not the best of the last pass)
    fails: int = 0  # its failure-rate count F (ga.fail_rates), with the board's rate codes


class LearningBoard(Protocol):
    """The learning engine: a world model, a population, the hardware GA and its lanes."""

    cycles: int  # clock cycles of every learn so far

    def load_population(self, population: np.ndarray) -> None:
        """Write the population (P, 50); the next learn's first generation only evaluates it."""

    def observe(self, state: int, motion: int, next_state: int, crashed: bool) -> None:
        """Apply one observed transition (SPEC section 7 update rule) to the board's model."""

    def write_rates(self, changes) -> None:
        """Write failure-rate codes (``ga.fail_rates``): (state, motion, code) triples, to every
        lane. A fresh or cleared board holds ``PRIOR_CODE`` for every pair."""

    def learn(self, generations: int, avoid: tuple[int, int] | None = None) -> LearnResult:
        """Run ``generations`` generations; the download: the best of the last, or with
        ``avoid`` = (state, motion) the fittest whose motion in ``state`` is another."""

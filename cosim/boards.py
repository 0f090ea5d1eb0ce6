"""The two EHW boards as the experiment loops see them (SPEC section 9).

The loops talk only to these interfaces; a backend is chosen by name:

- ``reference``: NumPy models (``ga.truth_table``, ``ga.world_model``, ``ga.evaluator``), fast;
- ``amaranth``: the Amaranth components in Amaranth's simulator;
- ``cocotb``: the generated Verilog in Icarus, driven from inside a cocotb test.

The same seed gives the same controllers, trajectory and counts in every backend; the HDL
backends also count clock cycles.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

BACKENDS = ("reference", "amaranth", "cocotb")


@dataclass(frozen=True)
class EvalCounts:
    """What the evaluator returns for a population: arrays of shape (P,)."""

    crashes: np.ndarray
    loops: np.ndarray
    distance: np.ndarray
    cycles: int = 0  # clock cycles the hardware spent (0 for the reference backend)


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
        """(crashes, loops, distance) of every controller of ``population`` (P, 50)."""

"""The reference backend: NumPy models behind the board interfaces (``cosim.boards.interfaces``).

``ga.truth_table`` for the controller board, ``ga.world_model`` and ``ga.evaluator`` for the
evaluator board, ``ga.hardware_ga`` for the learning board: the bit-exact references every HDL
backend is checked against. Imports ``ga`` and the interfaces only.
"""

from __future__ import annotations

import time

import numpy as np

from cosim.boards.interfaces import BoardMismatch, EvalCounts, LearnResult
from ga.motions import DEFAULT_DISTANCE_RULE


class ReferenceControllerBoard:
    """The robot's board as a NumPy truth table (``ga.truth_table``), reflex in front.

    ``load`` computes the 256-entry table of the new controller at once, which is the reference
    for the HDL's shadow-configuration-then-commit: the robot never sees a half-loaded controller.
    """

    def __init__(self, reflex: bool = True):
        from ga.genome import N_ROWS, ROW_DTYPE

        self.cycles = 0
        self._reflex = bool(reflex)
        self._rows = np.zeros(N_ROWS, dtype=ROW_DTYPE)
        self._table = self._compute()

    def _compute(self) -> np.ndarray:
        from ga.truth_table import truth_tables

        return truth_tables(self._rows, reflex=self._reflex)

    def load(self, rows: np.ndarray) -> None:
        from ga.genome import validate_rows

        rows = validate_rows(rows)
        if rows.ndim != 1:
            raise ValueError(f"a controller board holds one genome (50,), got shape {rows.shape!r}")
        self._rows = rows.copy()
        self._table = self._compute()

    def set_reflex(self, enabled: bool) -> None:
        self._reflex = bool(enabled)
        self._table = self._compute()

    def motion(self, state: int) -> int:
        if not 0 <= state < self._table.shape[0]:
            raise ValueError(f"a world state is in 0..{self._table.shape[0] - 1}, got {state!r}")
        return int(self._table[state])


class ReferenceEvaluatorBoard:
    """The evaluator board as ``ga.world_model.WorldModel`` plus ``ga.evaluator.evaluate_population``."""

    def __init__(self, reflex: bool = True, distance_rule: str = DEFAULT_DISTANCE_RULE):
        from ga.fail_rates import prior_codes
        from ga.motions import motion_distances
        from ga.world_model import WorldModel

        motion_distances(distance_rule)  # refuses an unknown rule now, not at the first evaluation
        self.cycles = 0
        self.reflex = bool(reflex)
        self.distance_rule = distance_rule
        self.model = WorldModel()
        self.rates = prior_codes()
        self.time_s = 0.0  # CPU time spent in evaluate (beside the EHW's hardware time)

    def observe(self, state: int, motion: int, next_state: int, crashed: bool) -> None:
        self.model.observe(int(state), int(motion), int(next_state), bool(crashed))

    def write_rates(self, changes) -> None:
        for state, motion, code in changes:
            self.rates[state, motion] = code

    def evaluate(self, population: np.ndarray) -> EvalCounts:
        from ga.evaluator import evaluate_population

        t0 = time.process_time()  # CPU time: steady on a shared machine
        result = evaluate_population(population, self.model, reflex=self.reflex,
                                     distance_rule=self.distance_rule, rates=self.rates)
        self.time_s += time.process_time() - t0
        return EvalCounts(crashes=np.asarray(result.crashes), loops=np.asarray(result.loops),
                          distance=np.asarray(result.distance), fails=np.asarray(result.fails))


def checked_motion(read, state: int, reference, where: str, error=BoardMismatch) -> int:
    """The motion ``read(state)`` of a controller board, checked against its ``reference`` board
    (None: unchecked); a difference raises ``error`` naming ``where`` (the HDL and link boards)."""
    if not 0 <= int(state) < 256:
        raise ValueError(f"a world state is in 0..255, got {state!r}")
    motion = read(int(state))
    if reference is not None:
        expected = reference.motion(state)
        if motion != expected:
            raise error(f"{where}: motion {motion} in state {state}, the reference gives {expected}")
    return motion


class ReferenceLearningBoard:
    """The learning board as ``ga.hardware_ga.HardwareGA`` plus ``ga.world_model.WorldModel``
    and the rate codes (``rates``, (256, 8), ``ga.fail_rates``)."""

    def __init__(self, config, seed: int, population, reflex: bool = True,
                 distance_rule: str = DEFAULT_DISTANCE_RULE):
        from ga.fail_rates import prior_codes
        from ga.hardware_ga import HardwareGA
        from ga.motions import motion_distances
        from ga.world_model import WorldModel

        motion_distances(distance_rule)
        self.config = config
        self.reflex, self.distance_rule = bool(reflex), distance_rule
        self.model = WorldModel()
        self.rates = prior_codes()
        self.ga = HardwareGA(config, seed, population)
        self.cycles = 0
        self.time_s = 0.0  # CPU time of the reference's learns

    def load_population(self, population) -> None:
        self.ga.load_population(population)

    def observe(self, state: int, motion: int, next_state: int, crashed: bool) -> None:
        self.model.observe(int(state), int(motion), int(next_state), bool(crashed))

    def write_rates(self, changes) -> None:
        for state, motion, code in changes:
            self.rates[state, motion] = code

    def state_dict(self) -> dict:
        """The engine between two learns (``HardwareGA.state_dict``) and the cycle counter: with
        the world model and the rate codes (rebuilt by replaying the observations and the
        failure marks) the whole board."""
        return {"engine": self.ga.state_dict(), "cycles": self.cycles}

    def load_state(self, d: dict) -> None:
        from ga.hardware_ga import HardwareGA

        ga = HardwareGA.from_state_dict(d["engine"])
        if ga.config != self.config:
            raise ValueError(f"the saved engine has {ga.config!r}, this board {self.config!r}")
        self.ga, self.cycles = ga, int(d["cycles"])

    def learn(self, generations: int, avoid: tuple[int, int] | None = None) -> LearnResult:
        t0 = time.process_time()
        rows, counts, cycles = self.ga.learn(self.model, generations, self.reflex, self.distance_rule, avoid,
                                             self.rates)
        self.time_s += time.process_time() - t0
        self.cycles += cycles
        index = self.ga.download_index
        return LearnResult(rows, *counts, cycles=cycles, escaped=index != self.ga.best_index,
                           fails=int(self.ga.counts.fails[index]))


def checked_state_dict(board) -> dict:
    """``state_dict`` of a learning board whose engine state cannot be read (an HDL engine, or one
    behind the link: no port for its generator states and scores): the reference's beside it
    (``board.reference``, equal at every learn), with the board's cycle counter. Such a board has
    no ``load_state``: a resumed run replays its learns (``cosim.online.run.OnlineRun.load_state``)."""
    if board.reference is None:
        raise RuntimeError("the engine state comes from the reference board (check=True)")
    return {"engine": board.reference.ga.state_dict(), "cycles": board.cycles}


# backend -> "module:factory" of its learning board (by name, as make_boards does: the backend

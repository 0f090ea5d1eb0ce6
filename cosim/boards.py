"""The two EHW boards as the experiment loops see them (SPEC section 9).

The loops talk only to these interfaces; a backend is chosen by name:

- ``reference``: NumPy models (``ga.truth_table``, ``ga.world_model``, ``ga.evaluator``), fast;
- ``amaranth``: the Amaranth components in Amaranth's simulator;
- ``cocotb``: the generated Verilog in Icarus, driven from inside a cocotb test;
- ``serial``: real boards behind the UART host link (``cosim.link_boards``);
- ``uart``: the board top with its UART in Verilator, reached over a simulated serial line by
  the same host code (``cosim.uart_backend``).

The same seed gives the same controllers, trajectory and counts in every backend; the HDL
backends also count clock cycles.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from cosim.errors import UserError
from ga.motions import DEFAULT_DISTANCE_RULE

# The one place a backend is named: name -> (the module that registers its boards with
# ``register_backend``, or None for the reference below; a launcher "module:function" for a backend
# whose boards exist only inside a simulator that must be started first, or None). Adding a backend
# is one line here plus its module.
_BACKENDS = {
    "reference": (None, None),
    "amaranth": ("cosim.amaranth_backend", None),
    "cocotb": ("cosim.cocotb_backend", "cosim.cocotb_launch:launch"),
    "serial": ("cosim.link_boards", None),  # real boards behind the UART host link
    "uart": ("cosim.uart_backend", "cosim.uart_backend:launch"),  # the link top in Verilator
}
BACKENDS = tuple(_BACKENDS)


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


# --------------------------------------------------------------------------------------------
# The reference backend: NumPy models behind the two board interfaces.


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


class BackendUnavailable(UserError, RuntimeError):
    """A board backend that is named in SPEC section 9 but not installed in this checkout yet."""


# name -> factory(reflex: bool, distance_rule: str = DEFAULT_DISTANCE_RULE, **options) ->
# (ControllerBoard, EvaluatorBoard); distance_rule: dist[a] of the evaluator
# (ga.motions.DISTANCE_RULES). The HDL backends register themselves here (``register_backend``)
# so that the loops never import them directly.
_FACTORIES: dict = {}


def register_backend(name: str, factory) -> None:
    """Make ``make_boards(name, ...)`` call ``factory(reflex=..., **options)``."""
    if name not in BACKENDS:
        raise ValueError(f"unknown backend {name!r}; SPEC section 9 names {BACKENDS!r}")
    _FACTORIES[name] = factory


def _reference_factory(reflex: bool = True, distance_rule: str = DEFAULT_DISTANCE_RULE, **options):
    if options:
        raise TypeError(f"the reference backend takes only distance_rule, got {sorted(options)!r}")
    return ReferenceControllerBoard(reflex=reflex), ReferenceEvaluatorBoard(reflex=reflex, distance_rule=distance_rule)


register_backend("reference", _reference_factory)


def make_boards(backend: str = "reference", *, reflex: bool = True, **options):
    """A fresh (controller board, evaluator board) pair of the named backend.

    Both boards start empty: no controller loaded, an empty world model.
    """
    if backend not in BACKENDS:
        raise ValueError(f"unknown backend {backend!r}; choose one of {BACKENDS!r}")
    module = _BACKENDS[backend][0]
    if backend not in _FACTORIES and module is not None:
        # The HDL backends register from their own modules; importing them here keeps the
        # reference path free of Amaranth/cocotb imports.
        import importlib

        try:
            importlib.import_module(module)
        except ModuleNotFoundError as error:
            if error.name != module:
                raise
    if backend not in _FACTORIES:
        raise BackendUnavailable(
            f"backend {backend!r} is not available in this checkout yet (no module registers it); "
            f"use --backend reference"
        )
    return _FACTORIES[backend](reflex=reflex, **options)


def launcher(backend: str):
    """The function ``launch(config, args) -> exit status`` that starts ``backend``'s simulator
    and runs the lifetime inside it, or None when the loop can call the boards directly."""
    if backend not in BACKENDS:
        raise ValueError(f"unknown backend {backend!r}; choose one of {BACKENDS!r}")
    target = _BACKENDS[backend][1]
    if target is None:
        return None
    import importlib

    module, name = target.split(":")
    return getattr(importlib.import_module(module), name)


# --------------------------------------------------------------------------------------------
# The learning board (SPEC section 12): the GA and the evaluator lanes on one chip. The host sends
# observations and "learn G generations"; only the download comes back.


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


class ReferenceLearningBoard:
    """The learning board as ``ga.hardware_ga.HardwareGA`` plus ``ga.world_model.WorldModel``
    and the rate codes (``rates``, (256, 8), ``ga.fail_rates``)."""

    def __init__(self, config, seed: int, population, reflex: bool = True,
                 distance_rule: str = "covered"):
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
    no ``load_state``: a resumed run replays its learns (``cosim.online.OnlineRun.load_state``)."""
    if board.reference is None:
        raise RuntimeError("the engine state comes from the reference board (check=True)")
    return {"engine": board.reference.ga.state_dict(), "cycles": board.cycles}


# backend -> "module:factory" of its learning board (by name, as make_boards does: the backend
# modules import this one, not the reverse). cocotb's exists only inside the simulator (launcher),
# and so does uart's (the same launcher as its board pair: ``cosim.uart_backend``).
_LEARNING_FACTORIES = {
    "amaranth": "cosim.amaranth_learning:AmaranthLearningBoard",
    "cocotb": "cosim.cocotb_learning:make_cocotb_learning_board",
    "uart": "cosim.uart_backend:make_uart_learning_boards",
    "serial": "cosim.link_learning:make_serial_learning_boards",
}
# The backends whose learning factory gives (controller board, learning board): the learner top
# (``hdl.learner_link.LearnerLinkTop``) holds the controller board beside the engine behind one
# link, so the run makes no board pair of ``make_boards`` (that would ask for an ehw-system board).
_LEARNING_TOPS = ("uart", "serial")
LEARNING_BACKENDS = ("reference", *_LEARNING_FACTORIES)


def make_learning_boards(backend: str, config, seed: int, population, *, controller=None,
                         reflex: bool = True, distance_rule: str = "covered"):
    """(controller board, learning board) of the named backend: the learning board holds
    ``population``, its generators seeded with ``seed`` (32 bits), and an empty world model. On a
    learner top (``_LEARNING_TOPS``) both boards come from the top; elsewhere the learning board
    goes beside ``controller`` (the one of ``make_boards(backend)``)."""
    if backend not in LEARNING_BACKENDS:
        raise BackendUnavailable(
            f"no learning board for backend {backend!r} yet; --ga hardware runs on {LEARNING_BACKENDS!r}")
    if (controller is None) != (backend in _LEARNING_TOPS):
        raise ValueError(f"the {backend} learning board " + ("brings its own controller board" if controller
                         is not None else "goes beside the controller board of make_boards"))
    if backend == "reference":
        return controller, ReferenceLearningBoard(config, seed, population, reflex, distance_rule)
    import importlib

    module, name = _LEARNING_FACTORIES[backend].split(":")
    made = getattr(importlib.import_module(module), name)(config, seed, population, reflex=reflex,
                                                          distance_rule=distance_rule)
    return made if backend in _LEARNING_TOPS else (controller, made)


def learning_top_drives(backend: str) -> bool:
    """Whether the learning board of ``backend`` comes with its own controller board (a learner
    top: the run then makes no ``make_boards`` pair)."""
    return backend in _LEARNING_TOPS

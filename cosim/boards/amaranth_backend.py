"""The ``amaranth`` board backend: both EHW boards cycle-accurate in Amaranth's simulator.

    ehw sim --backend amaranth --seed 1      (make sim BACKEND=amaranth)

One ``hdl.system_top.SystemTop`` (controller EHW + evaluator EHW + population streamer) lives in
one ``amaranth.sim.Simulator`` for the whole run. Amaranth 0.5 cannot add a testbench to a running
simulation, so a single testbench serves *jobs*: a board call puts a coroutine (from
``hdl.system_top.SystemHost``) in the job slot and calls ``Simulator.advance()`` until the
testbench has run it; between calls the testbench waits in 1 ps steps (no clock edge passes, so
the boards' cycle counts are exactly the edges the jobs awaited). The cocotb backend drives the
same top with the same ``SystemHost``, so the two HDL backends spend the same cycles.

Each board also keeps the reference model (``cosim.boards.reference`` reference backend) beside the HDL and
checks every motion and every evaluation against it (``check=True``, the default): a divergence
raises :class:`BoardMismatch` at once, with the call that diverged. The time the reference spent
is kept (``reference_time_s``) to print the software time beside the hardware time.

The board classes (:class:`HDLControllerBoard`, :class:`HDLEvaluatorBoard`) only need a system
with ``host`` and ``call(job, *args)``: the cocotb backend reuses them over its own system. Also
here: :class:`BoardLog` / :class:`LoggedBoards` (what crossed the board interface, to compare
backends) and the evaluator's spot-check mode (``EHW_HDL_SAMPLE``, see docs/hdl_in_the_loop.md).
"""

from __future__ import annotations

import time

import numpy as np

from base import environ
from cosim.boards.hardware_time import CLOCK_HZ
from cosim.boards.interfaces import BoardMismatch, EvalCounts
from cosim.boards.reference import ReferenceControllerBoard, ReferenceEvaluatorBoard, checked_motion
from cosim.boards.registry import register_backend
from ga.motions import DEFAULT_DISTANCE_RULE
from hdl.ports import AmaranthPins

IDLE_S = 1e-12  # the serving testbench's wait between jobs: far below a clock period
SIM_PERIOD_S = 1 / CLOCK_HZ  # the simulated clock (the hardware time uses EHW_CLOCK_HZ)


class SimulatorJobs:
    """One Amaranth Simulator kept alive across calls: a serving testbench runs *jobs*
    (coroutines) put in its slot by ``call``, waiting ``IDLE_S`` between them. Subclasses build
    ``self.sim`` with ``add_testbench(self._serve)`` and set up their host in ``_attach(ctx)``."""

    _job = None
    _finished = False
    _result = None
    _error: BaseException | None = None

    def _attach(self, ctx) -> None:
        """Called once with the serving testbench's context, before the first job."""

    async def _serve(self, ctx) -> None:
        self._attach(ctx)
        while True:
            if self._job is None:
                await ctx.delay(IDLE_S)
                continue
            job, self._job = self._job, None
            try:
                self._result = await job()
            except BaseException as error:  # handed to the caller of call()
                self._error = error
            self._finished = True

    def call(self, job, *args):
        """Run the coroutine ``job(*args)`` inside the simulation; return its result."""

        async def bound():
            return await job(*args)

        self._job, self._finished, self._error = bound, False, None
        while not self._finished:
            self.sim.advance()
        if self._error is not None:
            raise self._error
        return self._result


class AmaranthSystem(SimulatorJobs):
    """One SystemTop in one Simulator, kept alive across calls; ``call(job)`` runs a coroutine
    function ``job(host)`` in the simulation and returns its result."""

    def __init__(self, reflex: bool = True, vcd: str | None = None, distance_rule: str = DEFAULT_DISTANCE_RULE):
        from amaranth.sim import Simulator

        from hdl.system_top import SystemHost, SystemTop

        self.dut = SystemTop(distance_rule=distance_rule)
        self.pins = AmaranthPins(self.dut)
        self.host = SystemHost(self.pins)
        self.sim = Simulator(self.dut)
        self.sim.add_clock(SIM_PERIOD_S)
        self.sim.add_testbench(self._serve)
        self._vcd = None
        if vcd:
            self._vcd = self.sim.write_vcd(vcd)
            self._vcd.__enter__()
        self.call(self.host.boot)
        self.host.set_reflex(reflex)

    def _attach(self, ctx) -> None:
        self.pins.ctx = ctx

    def close(self) -> None:
        if self._vcd is not None:
            self._vcd.__exit__(None, None, None)
            self._vcd = None


# -- the two boards over a shared system ----------------------------------------------------------


class BoardLog:
    """What crossed the board interface, for comparing backends: every downloaded genome (hex)
    and a digest of every evaluation's (crashes, loops, distance, fails)."""

    def __init__(self):
        self.downloads: list[str] = []
        self.evaluations: list[str] = []

    def download(self, rows) -> None:
        from ga.genome import hex_from_rows

        self.downloads.append(hex_from_rows(rows))

    def evaluation(self, counts: EvalCounts) -> None:
        import hashlib

        data = np.stack([np.asarray(counts.crashes), np.asarray(counts.loops),
                         np.asarray(counts.distance), np.asarray(counts.fails)]).astype(np.int64)
        self.evaluations.append(hashlib.sha1(data.tobytes()).hexdigest()[:16])

    def to_dict(self, motions=()) -> dict:
        return {"motions": bytes(motions).hex(), "downloads": self.downloads,
                "evaluations": self.evaluations}

    def write(self, path, motions=()) -> None:
        import json
        from pathlib import Path

        Path(path).write_text(json.dumps(self.to_dict(motions), indent=1) + "\n")


class LoggedBoards:
    """Wrap any (controller, evaluator) pair so that a ``BoardLog`` records its calls."""

    def __init__(self, controller, evaluator, log: BoardLog | None = None):
        self.log = log or BoardLog()
        self.controller = _LoggedController(controller, self.log)
        self.evaluator = _LoggedEvaluator(evaluator, self.log)


class _LoggedController:
    def __init__(self, board, log):
        self._board, self.log = board, log

    def __getattr__(self, name):
        return getattr(self._board, name)

    def load(self, rows):
        self._board.load(rows)
        self.log.download(rows)


class _LoggedEvaluator:
    def __init__(self, board, log):
        self._board, self.log = board, log

    def __getattr__(self, name):
        return getattr(self._board, name)

    def evaluate(self, population):
        counts = self._board.evaluate(population)
        self.log.evaluation(counts)
        return counts


class HDLControllerBoard:
    """ControllerBoard over a system whose ``call(job, *args)`` runs ``SystemHost`` coroutines
    (Amaranth: ``AmaranthSystem.call``; cocotb: ``cocotb.task.resume``)."""

    def __init__(self, system, reflex: bool = True, check: bool = True, log: BoardLog | None = None):
        self.system = system
        self.host = system.host
        self.reference = ReferenceControllerBoard(reflex=reflex) if check else None
        self.log = log if log is not None else BoardLog()

    @property
    def cycles(self) -> int:
        return self.host.controller_cycles

    def load(self, rows: np.ndarray) -> None:
        from ga.genome import validate_rows

        rows = validate_rows(rows)
        if rows.ndim != 1:
            raise ValueError(f"a controller board holds one genome (50,), got shape {rows.shape!r}")
        self.system.call(self.host.load, rows)
        self.log.download(rows)
        if self.reference is not None:
            self.reference.load(rows)

    def set_reflex(self, enabled: bool) -> None:
        self.system.call(self.host.reflex, bool(enabled))
        if self.reference is not None:
            self.reference.set_reflex(enabled)

    def motion(self, state: int) -> int:
        return checked_motion(lambda s: self.system.call(self.host.motion, s), state, self.reference,
                              "controller board")


SAMPLE_ENV = "EHW_HDL_SAMPLE"


def sample_default() -> int:
    """Controllers per evaluation that the HDL evaluates when sampling (``EHW_HDL_SAMPLE``; 0:
    all of them, the default)."""
    return environ.read(SAMPLE_ENV, 0)


def sample_indices(population: int, sample: int, call: int) -> np.ndarray:
    """``sample`` evenly spaced indices of a population, shifted by one each call so that every
    position is covered over successive evaluations."""
    stride = max(1, population // sample)
    return np.unique((call + np.arange(sample) * stride) % population)


class HDLEvaluatorBoard:
    """EvaluatorBoard over the same system; ``cycles`` counts the evaluator's own cycles.

    ``sample`` > 0 (spot-check mode, for runs too long to simulate whole): the HDL evaluates only
    ``sample`` controllers of each population (:func:`sample_indices`), the reference model the
    whole population; the HDL's results must equal the reference's, and the reference's are
    returned. ``cycles`` is then the cycle model's count for the whole population (exact for the
    HDL: ``cosim.boards.hardware_time.stream_cycles``) and ``simulated_cycles`` what was simulated.
    """

    def __init__(self, system, reflex: bool = True, check: bool = True, log: BoardLog | None = None,
                 sample: int | None = None, distance_rule: str = DEFAULT_DISTANCE_RULE):
        self.system = system
        self.host = system.host
        self.sample = sample_default() if sample is None else int(sample)
        if self.sample and not check:
            raise ValueError(f"sampling ({self.sample!r} controllers per evaluation) needs check=True")
        self.reference = ReferenceEvaluatorBoard(reflex=reflex, distance_rule=distance_rule) if check else None
        self.log = log if log is not None else BoardLog()
        self.reference_time_s = 0.0  # CPU time of the reference evaluations (check=True)
        self.evaluations = 0  # controllers evaluated
        self.calls = 0
        self.modeled_cycles = 0

    @property
    def cycles(self) -> int:
        return self.modeled_cycles if self.sample else self.host.evaluator_cycles

    @property
    def simulated_cycles(self) -> int:
        return self.host.evaluator_cycles

    @property
    def transfer_cycles(self) -> int:
        return self.host.transfer_cycles

    def observe(self, state: int, motion: int, next_state: int, crashed: bool) -> None:
        self.system.call(self.host.observe, int(state), int(motion), int(next_state), bool(crashed))
        if self.reference is not None:
            self.reference.observe(state, motion, next_state, crashed)

    def write_rates(self, changes) -> None:
        changes = [(int(s), int(a), int(code)) for s, a, code in changes]
        self.system.call(self.host.write_rates, changes)
        if self.reference is not None:
            self.reference.write_rates(changes)

    def evaluate(self, population: np.ndarray) -> EvalCounts:
        from cosim.boards.hardware_time import stream_cycles
        from ga.genome import validate_rows

        population = validate_rows(population)
        if population.ndim != 2:
            raise ValueError(f"a population is (P, 50), got shape {population.shape!r}")
        index = np.arange(len(population))
        if self.sample and self.sample < len(population):
            index = sample_indices(len(population), self.sample, self.calls)
        self.calls += 1
        counts, cycles = self.system.call(self.host.evaluate, population[index])
        arr = np.asarray(counts, dtype=np.int64).reshape(-1, 4)
        result = EvalCounts(crashes=arr[:, 0], loops=arr[:, 1], distance=arr[:, 2], fails=arr[:, 3],
                            cycles=int(cycles))
        self.evaluations += len(population)
        self.modeled_cycles += stream_cycles(len(population), self.host.model.n_states)
        if self.reference is not None:
            t0 = time.process_time()
            expected = self.reference.evaluate(population)
            self.reference_time_s += time.process_time() - t0
            for name in ("crashes", "loops", "distance", "fails"):
                got, want = getattr(result, name), np.asarray(getattr(expected, name))[index]
                if not np.array_equal(got, want):
                    i = int(np.flatnonzero(got != want)[0])
                    raise BoardMismatch(f"evaluator board: {name} of controller {int(index[i])} is {got[i]}, "
                                        f"the reference gives {want[i]} (model of {self.host.model.n_states} states)")
            if len(index) < len(population):
                result = EvalCounts(crashes=np.asarray(expected.crashes), loops=np.asarray(expected.loops),
                                    distance=np.asarray(expected.distance), fails=np.asarray(expected.fails),
                                    cycles=stream_cycles(len(population), self.host.model.n_states))
        self.log.evaluation(result)
        return result


def make_amaranth_boards(reflex: bool = True, check: bool = True, vcd: str | None = None,
                         sample: int | None = None, distance_rule: str = DEFAULT_DISTANCE_RULE):
    """A fresh (controller board, evaluator board) pair sharing one simulated SystemTop
    (``sample``: see :class:`HDLEvaluatorBoard`; default ``EHW_HDL_SAMPLE`` or 0, all).
    ``vcd``: dump the simulation there (``WAVES=1``: build/sim/amaranth_system_top.vcd)."""
    if vcd is None and environ.read("WAVES", False):
        from cosim.boards.cocotb_run import SIM_BUILD

        SIM_BUILD.mkdir(parents=True, exist_ok=True)
        vcd = str(SIM_BUILD / "amaranth_system_top.vcd")
    system = AmaranthSystem(reflex=reflex, vcd=vcd, distance_rule=distance_rule)
    if vcd:
        import atexit

        atexit.register(system.close)  # the VCD is complete when the process ends
    log = BoardLog()
    return (HDLControllerBoard(system, reflex, check, log=log),
            HDLEvaluatorBoard(system, reflex, check, log=log, sample=sample, distance_rule=distance_rule))


register_backend("amaranth", make_amaranth_boards)

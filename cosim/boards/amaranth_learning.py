"""The HDL learning boards: ``hdl.learner.Learner`` cycle-accurate behind the LearningBoard interface.

:class:`HDLLearningBoard` is the board over any engine: a ``call(job, *args)`` that runs a
coroutine in the simulator and an ``hdl.learning_system_top.LearnerHost`` over that simulator's
pins (the one host driver). The reference learning board (``cosim.boards.reference``) runs beside it and
every learn is checked against it (``check=True``): the download, its counts and fail count, and
the cycles.

- ``amaranth`` (:class:`AmaranthLearningBoard`, here): a bare ``Learner`` in Amaranth's simulator,
  as ``cosim.boards.amaranth_backend``: one Simulator for the whole run, one serving testbench that runs
  the jobs the board calls put in its slot. Slow (a few hundred cycles per second of the
  simulator): for small populations and tests.
- ``cocotb`` (``cosim.boards.cocotb_learning``): the engine's Verilog in ``learning_system_top`` under
  cocotb (Icarus or Verilator).
"""

from __future__ import annotations

import numpy as np

from cosim.boards.amaranth_backend import SIM_PERIOD_S, BoardMismatch, SimulatorJobs
from cosim.boards.interfaces import LearnResult
from cosim.boards.reference import ReferenceLearningBoard, checked_state_dict
from ga.motions import DEFAULT_DISTANCE_RULE


class HDLLearningBoard:
    """A LearningBoard on an HDL engine: ``call`` runs a job (a coroutine of ``host``, a
    ``LearnerHost``) in the simulator. ``cycles``: the engine's clock edges of every learn (its
    ``cycles`` register + the start edge, checked against the reference's count)."""

    def __init__(self, call, host, config, seed: int, population, reflex: bool = True,
                 distance_rule: str = DEFAULT_DISTANCE_RULE, check: bool = True):
        from ga.world_model import WorldModel

        self.call, self.host = call, host
        self.config, self.reflex = config, bool(reflex)
        self.reference = ReferenceLearningBoard(config, seed, population, reflex, distance_rule) if check else None
        self.mirror = WorldModel()  # the host side of the update rule (what the entry becomes)
        self.cycles = 0
        self.call(self._boot, int(seed), np.asarray(population))

    async def _boot(self, seed, population):
        await self.host.wait_ready()
        await self.host.seed(seed)
        await self.host.write_population(population)

    def load_population(self, population) -> None:
        self.call(self.host.write_population, np.asarray(population))
        if self.reference is not None:
            self.reference.load_population(population)

    def observe(self, state: int, motion: int, next_state: int, crashed: bool) -> None:
        self.call(self.host.observe, self.mirror, int(state), int(motion), int(next_state), bool(crashed))
        if self.reference is not None:
            self.reference.observe(state, motion, next_state, crashed)

    def write_rates(self, changes) -> None:
        changes = [tuple(map(int, change)) for change in changes]
        self.call(self.host.write_rates, changes)
        if self.reference is not None:
            self.reference.write_rates(changes)

    state_dict = checked_state_dict  # the reference's engine state (no load_state: resume replays)

    async def _learn(self, generations, avoid):
        index, counts, fails, _score, register, escaped = await self.host.learn(generations, self.reflex, avoid)
        rows = await self.host.read_genome(index)
        return np.array(rows, dtype=np.uint32), counts + (fails,), register + 1, escaped

    def learn(self, generations: int, avoid: tuple[int, int] | None = None) -> LearnResult:
        rows, counts, edges, escaped = self.call(self._learn, int(generations), avoid)
        self.cycles += edges
        result = LearnResult(rows, *counts[:3], cycles=edges, escaped=escaped, fails=counts[3])
        if self.reference is not None:
            want = self.reference.learn(generations, avoid)
            want_counts = (want.crashes, want.loops, want.distance, want.fails)
            if not (np.array_equal(want.rows, rows) and want_counts == counts and want.cycles == edges
                    and want.escaped == escaped):
                raise BoardMismatch(f"learn({generations}, avoid={avoid}): HDL {counts} in {edges} "
                                    f"cycles, reference {want_counts} in {want.cycles} (crashes, loops, "
                                    f"distance, fails); downloads equal: {np.array_equal(want.rows, rows)}")
        return result


class _LearnerSimulator(SimulatorJobs):
    """A bare ``Learner`` in Amaranth's simulator, serving jobs over ``AmaranthPins``."""

    def __init__(self, config, distance_rule: str):
        from amaranth.sim import Simulator

        from hdl.learner import Learner
        from hdl.ports import AmaranthPins

        self.dut = Learner(config, distance_rule)
        self.pins = AmaranthPins(self.dut)
        self.sim = Simulator(self.dut)
        self.sim.add_clock(SIM_PERIOD_S)
        self.sim.add_testbench(self._serve)

    def _attach(self, ctx) -> None:
        self.pins.ctx = ctx


class AmaranthLearningBoard(HDLLearningBoard):
    def __init__(self, config, seed: int, population, reflex: bool = True,
                 distance_rule: str = DEFAULT_DISTANCE_RULE, check: bool = True):
        from hdl.learning_system_top import LearnerHost

        self.simulator = _LearnerSimulator(config, distance_rule)
        super().__init__(self.simulator.call, LearnerHost(self.simulator.pins, prefix=""), config, seed,
                         population, reflex, distance_rule, check)

"""The ``amaranth`` learning board: ``hdl.learner.Learner`` cycle-accurate in Amaranth's simulator.

As ``cosim.amaranth_backend``: one Simulator for the whole run, one serving testbench that runs
*jobs* (coroutines of ``hdl.learner.LearnerSimHost``) put in its slot by the board calls, waiting
in 1 ps steps between them. The reference learning board (``cosim.boards``) runs beside it and
every learn is checked against it (``check=True``): the download, its counts and the cycles.
Slow (a few hundred cycles per second of the simulator): for small populations and tests.
"""

from __future__ import annotations

import numpy as np

from cosim.amaranth_backend import SIM_PERIOD_S, BoardMismatch, SimulatorJobs
from cosim.boards import LearnResult, ReferenceLearningBoard


class AmaranthLearningBoard(SimulatorJobs):
    def __init__(self, config, seed: int, population, reflex: bool = True,
                 distance_rule: str = "covered", check: bool = True):
        from amaranth.sim import Simulator

        from ga.world_model import WorldModel
        from hdl.learner import Learner, LearnerSimHost

        self.config, self.reflex = config, bool(reflex)
        self.reference = ReferenceLearningBoard(config, seed, population, reflex, distance_rule) if check else None
        self.mirror = WorldModel()  # the host side of the update rule (what the entry becomes)
        self.dut = Learner(config, distance_rule)
        self.sim = Simulator(self.dut)
        self.sim.add_clock(SIM_PERIOD_S)
        self.sim.add_testbench(self._serve)
        self._host_class = LearnerSimHost
        self.host = None
        self.cycles = 0
        self.call(self._boot, int(seed), np.asarray(population))

    def _attach(self, ctx) -> None:
        self.host = self._host_class(ctx, self.dut)

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

    def state_dict(self) -> dict:
        """The engine state, from the reference beside the HDL (equal at every learn): what the
        checkpoint holds. No ``load_state``: the engine has no port to load generator states and
        scores, so a resumed run replays the learns (``cosim.online.OnlineRun.load_state``)."""
        if self.reference is None:
            raise RuntimeError("the engine state comes from the reference board (check=True)")
        return {"engine": self.reference.ga.state_dict(), "cycles": self.cycles}

    async def _learn(self, generations, avoid):
        index, counts, _score, _cycles, edges = await self.host.learn(generations, self.reflex, avoid)
        escaped = avoid is not None and bool(self.host.ctx.get(self.dut.escape_found)) \
            and index != self.host.ctx.get(self.dut.best_index)
        rows = await self.host.read_genome(index)
        return np.array(rows, dtype=np.uint32), counts, edges, escaped

    def learn(self, generations: int, avoid: tuple[int, int] | None = None) -> LearnResult:
        rows, counts, edges, escaped = self.call(self._learn, int(generations), avoid)
        self.cycles += edges
        result = LearnResult(rows, *counts, cycles=edges, escaped=escaped)
        if self.reference is not None:
            want = self.reference.learn(generations, avoid)
            if not (np.array_equal(want.rows, rows) and (want.crashes, want.loops, want.distance) == counts
                    and want.cycles == edges):
                raise BoardMismatch(f"learn({generations}, avoid={avoid}): Amaranth {counts} in {edges} "
                                    f"cycles, reference {(want.crashes, want.loops, want.distance)} in "
                                    f"{want.cycles}; downloads equal: {np.array_equal(want.rows, rows)}")
        return result

"""The learning engine (``hdl.learner.Learner``) in Amaranth's simulator: a whole run
(:func:`simulate_learning`), for the tests, driven by the one host driver of the engine's ports
(``hdl.learning_system_top.LearnerHost``, the same the learning boards use)."""

from __future__ import annotations

from ga import hardware_ga as hg
from ga.motions import DEFAULT_DISTANCE_RULE
from hdl.learner import Learner
from hdl.learning_system_top import LearnerHost
from hdl.ports import AmaranthPins


class _CountingPins(AmaranthPins):
    """Amaranth pins that count the clock edges (a learn's edges from its start strobe to done)."""

    cycle = 0

    async def tick(self) -> None:
        await super().tick()
        self.cycle += 1

    async def wait(self, name: str) -> None:
        await self.tick()
        while not self.get(name):
            await self.tick()


def simulate_learning(config: hg.HardwareGAConfig, seed: int, population, phases,
                      read_population: bool = True, distance_rule: str = DEFAULT_DISTANCE_RULE):
    """Run a Learner in Amaranth's simulator: seed it, write ``population``, then for each
    ``(observations, generations[, avoid[, rates]])`` of ``phases`` apply the observations (a list
    of (state, motion, next_state, crashed), host mirror ``ga.world_model.WorldModel``), write the
    rate codes (a list of (state, motion, code)) and learn. Returns one dict per phase: download
    index, counts, fails, score, cycles, edges, population (if read)."""
    from amaranth.sim import Simulator

    from ga.world_model import WorldModel

    dut = Learner(config, distance_rule)
    out = []

    async def testbench(ctx):
        pins = _CountingPins(dut, ctx)
        host = LearnerHost(pins, prefix="")
        await host.wait_ready()
        await host.seed(seed)
        await host.write_population(population)
        mirror = WorldModel()
        for observations, generations, *extra in phases:
            avoid, rates = (list(extra) + [None, ()])[:2]
            for obs in observations:
                await host.observe(mirror, *obs)
            await host.write_rates(rates)
            first = pins.cycle
            best, counts, fails, score, cycles, _ = await host.learn(generations, avoid=avoid)
            edges = pins.cycle - first
            record = {"best_index": best, "counts": counts, "fails": fails, "score": score, "cycles": cycles,
                      "edges": edges, "n_states": mirror.n_states}
            if read_population:
                record["population"] = [await host.read_genome(i) for i in range(config.population)]
            else:
                record["best"] = await host.read_genome(best)
            out.append(record)

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(testbench)
    sim.run()
    return out

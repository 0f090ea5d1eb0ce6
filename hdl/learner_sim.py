"""The learning engine (``hdl.learner.Learner``) in Amaranth's simulator: its host side
(:class:`LearnerSimHost`) and a whole run (:func:`simulate_learning`), for the tests."""

from __future__ import annotations

from ga import hardware_ga as hg
from ga.genome import N_ROWS
from hdl.learner import Learner


class LearnerSimHost:
    """The host side of the learner's ports in Amaranth's simulator (testbench context ``ctx``)."""

    def __init__(self, ctx, dut: Learner):
        from hdl.evaluator_sim import EvaluatorSimHost

        self.ctx, self.dut = ctx, dut
        self.model_host = EvaluatorSimHost(ctx, dut)  # the same model/state ports and ready
        self.cycle = 0

    async def tick(self):
        await self.ctx.tick()
        self.cycle += 1
        self.model_host.cycle = self.cycle

    async def wait_ready(self):
        while not self.ctx.get(self.dut.ready):
            await self.tick()

    async def write_model(self, model):
        await self.model_host.write_model(model)
        self.cycle = self.model_host.cycle

    async def observe(self, model, state, motion, next_state, crashed):
        await self.model_host.observe(model, state, motion, next_state, crashed)
        self.cycle = self.model_host.cycle

    async def write_rates(self, changes):
        """Failure-rate codes (``ga.fail_rates``): one (state, motion, code) a cycle, every lane."""
        await self.model_host.write_rates(changes)
        self.cycle = self.model_host.cycle

    async def seed(self, seed: int):
        self.ctx.set(self.dut.seed, int(seed))
        self.ctx.set(self.dut.seed_we, 1)
        await self.tick()
        self.ctx.set(self.dut.seed_we, 0)

    async def write_population(self, population):
        ctx, dut = self.ctx, self.dut
        for i, genome in enumerate(population):
            for r, word in enumerate(genome):
                ctx.set(dut.pop_index, i)
                ctx.set(dut.pop_row, r)
                ctx.set(dut.pop_data, int(word))
                ctx.set(dut.pop_we, 1)
                await self.tick()
        ctx.set(dut.pop_we, 0)

    async def read_genome(self, index: int) -> list[int]:
        ctx, dut = self.ctx, self.dut
        rows = []
        for r in range(N_ROWS):  # the edge samples the address; the data is there after it
            ctx.set(dut.pop_index, index)
            ctx.set(dut.pop_row, r)
            await self.tick()
            rows.append(ctx.get(dut.pop_rdata))
        return rows

    async def learn(self, generations: int, reflex: bool = True, avoid=None):
        """Run ``generations`` passes. Returns (download index, (crashes, loops, distance), fails,
        score, cycles register, clock edges from the start strobe to done); the download is the
        escape child when ``avoid`` = (state, motion) is given and one exists, else the best."""
        ctx, dut = self.ctx, self.dut
        ctx.set(dut.reflex_en, int(reflex))
        ctx.set(dut.avoid_en, int(avoid is not None))
        if avoid is not None:
            ctx.set(dut.avoid_state, int(avoid[0]))
            ctx.set(dut.avoid_motion, int(avoid[1]))
        ctx.set(dut.generations, generations)
        ctx.set(dut.start, 1)
        first = self.cycle
        await self.tick()
        ctx.set(dut.start, 0)
        while not ctx.get(dut.done):
            await self.tick()
        kind = "escape" if avoid is not None and ctx.get(dut.escape_found) else "best"
        get = lambda name: ctx.get(getattr(dut, f"{kind}_{name}"))  # noqa: E731
        counts = (get("crashes"), get("loops"), get("distance"))
        return get("index"), counts, get("fails"), get("score"), ctx.get(dut.cycles), self.cycle - first


def simulate_learning(config: hg.HardwareGAConfig, seed: int, population, phases,
                      read_population: bool = True, distance_rule: str = "covered"):
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
        host = LearnerSimHost(ctx, dut)
        await host.wait_ready()
        await host.seed(seed)
        await host.write_population(population)
        mirror = WorldModel()
        for observations, generations, *extra in phases:
            avoid, rates = (list(extra) + [None, ()])[:2]
            for obs in observations:
                await host.observe(mirror, *obs)
            await host.write_rates(rates)
            best, counts, fails, score, cycles, edges = await host.learn(generations, avoid=avoid)
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

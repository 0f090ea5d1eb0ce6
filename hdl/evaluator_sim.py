"""The host side of the evaluator EHW (``hdl.evaluator_ehw``) in Amaranth's simulator: the
protocol of that module's docstring as coroutines (:class:`EvaluatorSimHost`), and
:func:`simulate_population`, a whole population on a fresh board. Used by the tests, the learner's
simulated host (``hdl.learner_sim``) and the benchmarks; the hardware itself is in
``hdl.evaluator_ehw``."""

from __future__ import annotations

from ga.world_model import WorldModel
from hdl.evaluator_ehw import EvaluatorEHW
from hdl.ports import AmaranthPins, write_rows

class EvaluatorSimHost:
    """The host side of the evaluator's ports in Amaranth's simulator (testbench context ``ctx``):
    the protocol of the module docstring as coroutines, over ``hdl.ports.AmaranthPins``. Inputs
    are set before ``ctx.tick()``, the edge samples them, outputs are read after it; ``cycle``
    counts the edges.
    """

    def __init__(self, ctx, dut):
        self.ctx, self.dut = ctx, dut
        self.pins = _CountingPins(AmaranthPins(dut, ctx), self)
        self.cycle = 0  # clock edges so far

    async def tick(self):
        await self.pins.tick()

    def set_entry(self, state, motion, next_state, crash, valid=1):
        pins = self.pins
        pins.set("model__state", int(state))
        pins.set("model__motion", int(motion))
        pins.set("model__next", int(next_state))
        pins.set("model__crash", int(crash))
        pins.set("model__valid", int(valid))
        pins.set("model__we", 1)

    async def wait_ready(self):
        while not self.pins.get("ready"):
            await self.tick()

    async def write_model(self, model: WorldModel):
        """Every valid entry and every state of S, one entry and one state per cycle (in parallel)."""
        pins = self.pins
        entries, states = model.entries(), model.states
        for i in range(max(len(entries), len(states))):
            assert pins.get("ready")
            if i < len(entries):
                self.set_entry(*entries[i])
            if i < len(states):
                pins.set("state_value", int(states[i]))
                pins.set("state_we", 1)
            await self.tick()
            pins.set("model__we", 0)
            pins.set("state_we", 0)

    async def write_entry(self, state, motion, next_state, crash, valid=1):
        self.set_entry(state, motion, next_state, crash, valid)
        await self.tick()
        self.pins.set("model__we", 0)

    async def observe(self, model: WorldModel, state, motion, next_state, crashed):
        """Apply one observation to the host's mirror ``model`` (SPEC section 7 rule, in
        ``ga.world_model``) and write the resulting entry and both states: 2 cycles, when ready."""
        model.observe(state, motion, next_state, crashed)
        pins = self.pins
        self.set_entry(state, motion, model.next_state[state, motion], model.crash[state, motion])
        pins.set("state_value", int(state))
        pins.set("state_we", 1)
        await self.tick()
        pins.set("model__we", 0)
        pins.set("state_value", int(next_state))
        await self.tick()
        pins.set("state_we", 0)

    async def write_rates(self, changes):
        """Failure-rate codes (``ga.fail_rates``): one (state, motion, code) per cycle, when ready."""
        pins = self.pins
        for state, motion, code in changes:
            assert pins.get("ready")
            pins.set("rate__state", int(state))
            pins.set("rate__motion", int(motion))
            pins.set("rate__code", int(code))
            pins.set("rate__we", 1)
            await self.tick()
        pins.set("rate__we", 0)

    async def add_state(self, state):
        self.pins.set("state_value", int(state))
        self.pins.set("state_we", 1)
        await self.tick()
        self.pins.set("state_we", 0)

    def results(self):
        get = self.pins.get
        return (get("crashes"), get("loops"), get("distance")), get("cycles")

    def fails(self) -> int:
        """The failure-rate count F of the last evaluation."""
        return self.pins.get("fails")

    async def evaluate(self, rows, reflex=True):
        """Load 50 rows (start with the last), wait for done. Returns (counts, cycles register,
        clock edges from the first row write to done: the per-controller cost, loading included)."""
        pins = self.pins
        pins.set("reflex_en", int(reflex))
        first = self.cycle
        await write_rows(pins, "row", rows, strobe="start")
        while not pins.get("done"):
            assert pins.get("busy") and not pins.get("ready")
            await self.tick()
        counts, cycles = self.results()
        return counts, cycles, self.cycle - first

    async def evaluate_overlapped(self, population, reflex=True):
        """Write the rows of controller i + 1 while controller i is evaluated; start each as soon
        as the board is ready and its rows are in. Returns ([counts], [cycles], total edges)."""
        if not self.dut.double_buffer:
            raise ValueError("overlapped loading needs EvaluatorEHW(double_buffer=True)")
        pins = self.pins
        pins.set("reflex_en", int(reflex))
        first = self.cycle
        counts, cycles = [], []
        loading, row = 0, 0  # the controller being loaded, its next row
        while len(counts) < len(population):
            write = loading < len(population) and row < len(population[loading])
            if write:
                pins.set("row__addr", row)
                pins.set("row__data", int(population[loading][row]))
            pins.set("row__we", int(write))
            loaded = loading < len(population) and row >= len(population[loading]) - 1
            start = loaded and pins.get("ready")
            pins.set("start", int(start))
            await self.tick()
            if write:
                row += 1
            if start:
                loading, row = loading + 1, 0
            if pins.get("done"):
                c, n = self.results()
                counts.append(c)
                cycles.append(n)
        pins.set("row__we", 0)
        pins.set("start", 0)
        return counts, cycles, self.cycle - first


class _CountingPins:
    """Pins that count the clock edges into ``host.cycle``."""

    def __init__(self, pins, host):
        self._pins, self._host = pins, host
        self.set, self.get = pins.set, pins.get

    async def tick(self):
        await self._pins.tick()
        self._host.cycle += 1


def simulate_population(model, population, reflex: bool = True, overlap: bool = True,
                        double_buffer: bool = True):
    """Evaluate ``population`` (P, 50) on ``model`` (a ``ga.world_model.WorldModel``) in a fresh
    EvaluatorEHW under Amaranth's simulator. Returns (counts [(crashes, loops, distance)] per
    controller, cycles register per controller, clock cycles from the first row written to the
    last done: the cost of the population, loading included)."""
    from amaranth.sim import Simulator

    dut = EvaluatorEHW(double_buffer=double_buffer)
    out = {}

    async def testbench(ctx):
        host = EvaluatorSimHost(ctx, dut)
        await host.wait_ready()
        await host.write_model(model)
        if overlap:
            out["result"] = await host.evaluate_overlapped(population, reflex)
        else:
            counts, cycles, total = [], [], 0
            for rows in population:
                c, n, cost = await host.evaluate(rows, reflex)
                counts.append(c)
                cycles.append(n)
                total += cost
            out["result"] = counts, cycles, total

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(testbench)
    sim.run()
    return out["result"]

"""cocotb testbench: the generated Verilog of a small learning engine against ga.hardware_ga.

The case (seed, initial population, phases of observations, rate codes and generations, and the
reference's expected best, counts, fails, score, cycles and population after each phase) comes as
JSON from tests/test_learner.py (``EHW_LEARNER_CASE``). The host seeds the generators, writes the
population, then per phase writes the observed transitions (the SPEC update rule applied by a host
mirror, ``ga.world_model``) and the failure-rate codes, starts the learning and compares
everything after done (the score is signed).

Timing: inputs change just after a falling edge; the rising edge in the middle of the cycle
samples them; outputs are read at the next falling edge.
"""

from __future__ import annotations

import json
import os

import cocotb
from cocotb.clock import Clock
from cocotb.triggers import FallingEdge

from ga.world_model import WorldModel

INPUTS = ("pop_index", "pop_row", "pop_data", "pop_we", "seed", "seed_we", "generations", "start",
          "model__state", "model__motion", "model__next", "model__crash", "model__valid", "model__we",
          "rate__state", "rate__motion", "rate__code", "rate__we",
          "state_value", "state_we", "clear", "reflex_en", "avoid_en", "avoid_state", "avoid_motion")


class Testbench:
    def __init__(self, dut):
        self.dut = dut
        self.cycle = 0
        Clock(dut.clk, 10, unit="ns").start(start_high=False)
        for name in INPUTS:
            getattr(dut, name).value = 0
        dut.rst.value = 0

    def get(self, name: str) -> int:
        value = getattr(self.dut, name).value
        return value.to_unsigned() if hasattr(value, "to_unsigned") else int(value)

    def get_signed(self, name: str) -> int:
        value = getattr(self.dut, name).value
        return value.to_signed() if hasattr(value, "to_signed") else value.signed_integer

    async def tick(self):
        await FallingEdge(self.dut.clk)
        self.cycle += 1

    async def reset(self):
        self.dut.rst.value = 1
        await self.tick()
        await self.tick()
        self.dut.rst.value = 0
        await self.tick()
        while not self.get("ready"):  # every lane sweeps its world-model RAM
            await self.tick()

    async def pulse(self, **values):
        for name, value in values.items():
            getattr(self.dut, name).value = int(value)
        await self.tick()
        for name in values:
            if name.endswith("we") or name == "start":
                getattr(self.dut, name).value = 0

    async def observe(self, mirror: WorldModel, state, motion, next_state, crashed):
        mirror.observe(state, motion, next_state, crashed)
        await self.pulse(model__state=state, model__motion=motion,
                         model__next=int(mirror.next_state[state, motion]),
                         model__crash=int(mirror.crash[state, motion]), model__valid=1, model__we=1,
                         state_value=state, state_we=1)
        await self.pulse(state_value=next_state, state_we=1)

    async def read_genome(self, index):
        rows = []
        for r in range(50):
            self.dut.pop_index.value, self.dut.pop_row.value = index, r
            await self.tick()
            rows.append(self.get("pop_rdata"))
        return rows


@cocotb.test()
async def learner_matches_reference(dut):
    case = json.loads(open(os.environ["EHW_LEARNER_CASE"]).read())
    tb = Testbench(dut)
    await tb.reset()
    await tb.pulse(seed=case["seed"], seed_we=1)
    for i, genome in enumerate(case["population"]):
        for r, word in enumerate(genome):
            await tb.pulse(pop_index=i, pop_row=r, pop_data=word, pop_we=1)
    mirror = WorldModel()
    dut.reflex_en.value = 1
    for phase, want in zip(case["phases"], case["expected"]):
        for obs in phase["observations"]:
            await tb.observe(mirror, *obs)
        for state, motion, code in phase["rates"]:
            await tb.pulse(rate__state=state, rate__motion=motion, rate__code=code, rate__we=1)
        avoid = phase["avoid"]
        dut.avoid_en.value = int(avoid is not None)
        if avoid is not None:
            dut.avoid_state.value, dut.avoid_motion.value = avoid
        first = tb.cycle
        await tb.pulse(generations=phase["generations"], start=1)
        while not tb.get("done"):
            await tb.tick()
        assert tb.cycle - first == want["cycles"], (tb.cycle - first, want["cycles"])
        kind = "escape" if avoid is not None and tb.get("escape_found") else "best"
        assert tb.get(f"{kind}_index") == want["best_index"]
        counts = [tb.get(f"{kind}_crashes"), tb.get(f"{kind}_loops"), tb.get(f"{kind}_distance")]
        assert counts == want["counts"] and tb.get(f"{kind}_fails") == want["fails"]
        assert tb.get_signed(f"{kind}_score") == want["score"], (tb.get_signed(f"{kind}_score"), want["score"])
        population = [await tb.read_genome(i) for i in range(len(want["population"]))]
        assert population == want["population"]
    dut._log.info("%d phases agree with the reference", len(case["phases"]))

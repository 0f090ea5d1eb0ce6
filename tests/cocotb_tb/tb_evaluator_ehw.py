"""cocotb testbench: the generated evaluator_ehw Verilog against the NumPy reference evaluator.

The same cases as the Amaranth-simulator test (tests/test_evaluator_cases.py, fixed seed): for
each world model the host clears the board, writes every entry and every state, then loads each
controller's 50 rows (start with the last row) and compares (crashes, loops, distance) with
``ga.evaluator`` and the cycle count with N + 1 (<= 2N + 60 per controller, loading included).
Also: overlapped loading, transitions written while idle count at the next evaluation, and a
start while busy is ignored. Started from pytest by tests/test_evaluator_ehw.py.

Timing: inputs change just after a falling edge; the rising edge in the middle of the cycle
samples them; outputs are read at the next falling edge (one loop step = one clock cycle).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import cocotb
from cocotb.clock import Clock
from cocotb.triggers import FallingEdge

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # tests/, for the shared cases

from ga.evaluator import evaluate_population  # noqa: E402
from ga.world_model import WorldModel  # noqa: E402
from hdl.ports import CocotbPins, write_rows  # noqa: E402
from test_evaluator_cases import case_rates, cases, constant_rows, random_model, rate_table, specific_rows  # noqa: E402

import numpy as np  # noqa: E402

INPUTS = ("row__addr", "row__data", "row__we", "model__state", "model__motion", "model__next",
          "model__crash", "model__valid", "model__we", "rate__state", "rate__motion", "rate__code", "rate__we",
          "state_value", "state_we", "clear", "reflex_en", "start")


def reference_counts(pop, model, reflex):
    result = evaluate_population(pop, model, reflex)
    return [result.row(i) for i in range(len(pop))]


class Testbench:
    """Clock, reset and host driver of one evaluator_ehw instance."""

    def __init__(self, dut):
        self.dut = dut
        self.cycle = 0
        Clock(dut.clk, 10, unit="ns").start(start_high=False)
        self.pins = CocotbPins(dut)
        for name in INPUTS:
            self.pins.set(name, 0)
        dut.rst.value = 0

    def get(self, name: str) -> int:
        value = getattr(self.dut, name).value
        return value.to_unsigned() if hasattr(value, "to_unsigned") else int(value)  # 1 bit: Logic

    async def tick(self):
        """Let one rising edge sample the inputs; outputs are settled when this returns."""
        await FallingEdge(self.dut.clk)
        self.cycle += 1

    async def reset(self):
        """Reset; the board then sweeps its RAM (Boot + 2048 cycles) and is ready with an empty model."""
        self.dut.rst.value = 1
        await self.tick()  # the first falling edge is the clock's start at t = 0: no rising edge yet
        await self.tick()
        self.dut.rst.value = 0
        await self.tick()  # Boot: the only cycle after reset where `ready` may read X in Icarus
        edges = 1
        while not self.get("ready"):
            await self.tick()
            edges += 1
        assert edges == 2049 and self.get("n_states") == 0, edges

    def set_entry(self, state, motion, next_state, crash, valid=1):
        for name, value in zip(("state", "motion", "next", "crash", "valid", "we"),
                               (state, motion, next_state, crash, valid, 1)):
            self.pins.set(f"model__{name}", int(value))

    async def clear(self):
        self.dut.clear.value = 1
        await self.tick()
        self.dut.clear.value = 0
        while not self.get("ready"):
            await self.tick()

    async def write_model(self, model: WorldModel):
        dut = self.dut
        entries, states = model.entries(), model.states
        for i in range(max(len(entries), len(states))):
            assert self.get("ready")
            if i < len(entries):
                self.set_entry(*entries[i])
            if i < len(states):
                dut.state_value.value, dut.state_we.value = int(states[i]), 1
            await self.tick()
            self.pins.set("model__we", 0)
            self.pins.set("state_we", 0)

    async def write_rates(self, changes):
        """Failure-rate codes (ga.fail_rates), one (state, motion, code) per cycle."""
        for state, motion, code in changes:
            assert self.get("ready")
            for name, value in (("state", state), ("motion", motion), ("code", code), ("we", 1)):
                self.pins.set(f"rate__{name}", int(value))
            await self.tick()
        self.pins.set("rate__we", 0)

    def results(self):
        return (self.get("crashes"), self.get("loops"), self.get("distance")), self.get("cycles")

    async def evaluate(self, rows, reflex=True):
        """Load the rows (start with the last), wait for done: (counts, cycles, edges used)."""
        dut = self.dut
        dut.reflex_en.value = int(reflex)
        first = self.cycle
        self.cycle += await write_rows(self.pins, "row", rows, strobe="start")
        while not self.get("done"):
            assert self.get("busy")
            await self.tick()
        counts, cycles = self.results()
        return counts, cycles, self.cycle - first


@cocotb.test()
async def shared_cases_match_reference(dut):
    tb = Testbench(dut)
    await tb.reset()
    checked = 0
    for name, model, pop, reflex in cases():
        await tb.clear()
        await tb.write_model(model)
        await tb.write_rates(case_rates(model))
        assert tb.get("n_states") == model.n_states, name
        n = model.n_states
        fails = evaluate_population(pop, model, reflex, rates=rate_table(case_rates(model))).fails
        for i, (rows, want) in enumerate(zip(pop, reference_counts(pop, model, reflex))):
            counts, cycles, cost = await tb.evaluate(rows, reflex)
            assert counts == want, f"{name}, genome {i}: Verilog {counts}, reference {want}"
            assert tb.get("fails") == fails[i], f"{name}, genome {i}: fails"
            assert cycles == n + 1, f"{name}: {cycles} cycles for N = {n}"
            assert cost <= 2 * n + 60, f"{name}: {cost} cycles per controller for N = {n}"
            checked += 1
    dut._log.info("%d controllers on %d models agree with the reference", checked, len(cases()))


@cocotb.test()
async def overlapped_loading(dut):
    """Rows of controller i + 1 are written while controller i runs; start as soon as ready."""
    tb = Testbench(dut)
    await tb.reset()
    rng = np.random.default_rng(5)
    model = random_model(rng, 70, 400, 0.1)
    pop = specific_rows(rng, 6)
    n = model.n_states
    await tb.write_model(model)
    dut.reflex_en.value = 1
    counts, first = [], tb.cycle
    loading, row = 0, 0
    while len(counts) < len(pop):
        write = loading < len(pop) and row < len(pop[loading])
        if write:
            tb.pins.set("row__addr", row)
            tb.pins.set("row__data", int(pop[loading][row]))
        tb.pins.set("row__we", int(write))
        start = loading < len(pop) and row >= len(pop[loading]) - 1 and tb.get("ready")
        dut.start.value = int(start)
        await tb.tick()
        if write:
            row += 1
        if start:
            loading, row = loading + 1, 0
        if tb.get("done"):
            counts.append(tb.results()[0])
            assert tb.results()[1] == n + 1
    tb.pins.set("row__we", 0)
    dut.start.value = 0
    assert counts == reference_counts(pop, model, True)
    total = tb.cycle - first
    assert total <= 50 + len(pop) * (n + 2), total
    dut._log.info("overlapped: %d controllers, N = %d, %d cycles in all", len(pop), n, total)


@cocotb.test()
async def idle_writes_count_and_busy_start_is_ignored(dut):
    tb = Testbench(dut)
    await tb.reset()
    rows = constant_rows(0)
    model = WorldModel()
    model.visit(1)
    await tb.write_model(model)
    assert (await tb.evaluate(rows, reflex=False))[0] == (0, 0, 0)
    for s, s2, crash in [(1, 2, False), (2, 1, False), (2, 2, True)]:
        model.observe(s, 0, s2, crash)
        tb.set_entry(s, 0, model.next_state[s, 0], model.crash[s, 0])
        dut.state_value.value, dut.state_we.value = s2, 1
        await tb.tick()
        tb.pins.set("model__we", 0)
        dut.state_we.value = 0
        counts = (await tb.evaluate(rows, reflex=False))[0]
        assert counts == reference_counts(rows[None], model, False)[0], (s, s2, crash)
    assert counts == (1, 0, 50)

    # A start held high while busy, and a model write then, are ignored.
    rng = np.random.default_rng(9)
    model = random_model(rng, 60, 300, 0.1)
    rows = specific_rows(rng, 1)[0]
    await tb.clear()
    await tb.write_model(model)
    n = model.n_states
    dut.reflex_en.value = 1
    tb.cycle += await write_rows(tb.pins, "row", rows, strobe="start")
    dut.start.value = 1  # held high while busy: must be ignored
    victim = int(model.states[0])
    busy_edges = 0
    while not tb.get("done"):
        assert tb.get("busy") and not tb.get("ready")
        tb.set_entry(victim, busy_edges % 8, victim, 1)  # start still high
        await tb.tick()
        busy_edges += 1
    dut.start.value = 0
    tb.pins.set("model__we", 0)
    assert busy_edges == n + 1
    counts, cycles = tb.results()
    assert counts == reference_counts(rows[None], model, True)[0] and cycles == n + 1
    await tb.tick()
    assert not tb.get("done") and tb.get("ready")
    assert (await tb.evaluate(rows))[0] == counts  # the writes while busy did not land


@cocotb.test(skip=os.environ.get("EHW_DISTANCE_RULE", "covered") == "covered")
async def distance_rule_matches_reference(dut):
    """Verilog built with EvaluatorEHW(distance_rule=EHW_DISTANCE_RULE) (an option, NOT the SPEC's
    dist[a]) against the reference under the same rule (tests/test_evaluator_ehw.py starts it)."""
    rule = os.environ["EHW_DISTANCE_RULE"]
    tb = Testbench(dut)
    await tb.reset()
    rng = np.random.default_rng(11)
    model = random_model(rng, 60, 400, 0.1)
    pop = specific_rows(rng, 6)
    want = evaluate_population(pop, model, True, distance_rule=rule)
    await tb.write_model(model)
    for i, rows in enumerate(pop):
        counts = (await tb.evaluate(rows, True))[0]
        assert counts == want.row(i), f"genome {i}: Verilog {counts}, reference {want.row(i)} ({rule})"

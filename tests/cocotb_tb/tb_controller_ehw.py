"""cocotb testbench: the generated controller_ehw Verilog against the NumPy reference.

A small Testbench object owns the clock and the host-side driver (row writes, commit, state
sweep); the tests load the shared vectors (tests/vectors.py) row by row, commit, and compare every
state's motion with ``ga.truth_table``; they also prove that a half-written shadow never reaches
``motion`` and that reset clears the board. Started from pytest by tests/test_controller_ehw.py.

Timing: inputs change just after a falling edge; the rising edge in the middle of the cycle
samples them; ``motion`` is read at the next falling edge (so one loop step = one clock cycle).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import cocotb
import numpy as np
from cocotb.clock import Clock
from cocotb.triggers import FallingEdge

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # tests/, for vectors

import vectors  # noqa: E402
from ga.genome import N_ROWS  # noqa: E402
from ga.motions import N_STATES, REFLEX_TABLE  # noqa: E402
from ga.truth_table import truth_tables  # noqa: E402
from hdl.ports import CocotbPins, write_rows  # noqa: E402

SEED = int(os.environ.get("EHW_TB_SEED", "11"))


class Testbench:
    """Clock, reset and host driver of one controller_ehw instance."""

    def __init__(self, dut):
        self.dut = dut
        Clock(dut.clk, 10, unit="ns").start(start_high=False)
        self.pins = CocotbPins(dut)
        for name in ("row__addr", "row__data", "row__we", "commit", "x", "reflex_en"):
            self.pins.set(name, 0)
        dut.rst.value = 0

    async def cycle(self) -> int:
        """Let one rising edge sample the inputs; return ``motion`` just after it."""
        await FallingEdge(self.dut.clk)
        return self.dut.motion.value.to_unsigned()

    async def reset(self):
        self.dut.rst.value = 1
        await self.cycle()
        self.dut.rst.value = 0

    async def write_row(self, addr: int, word: int, commit: bool = False):
        await write_rows(self.pins, "row", [word], strobe="commit" if commit else None, first_row=addr)
        return self.dut.motion.value.to_unsigned()

    async def commit(self):
        self.dut.commit.value = 1
        await self.cycle()
        self.dut.commit.value = 0

    async def load(self, rows, commit: bool = True):
        await write_rows(self.pins, "row", rows)
        if commit:
            await self.commit()

    async def table(self, reflex) -> np.ndarray:
        """Motions of all 256 states; ``reflex`` is one bool or one per state."""
        reflex = np.broadcast_to(np.asarray(reflex, dtype=bool), (N_STATES,))
        got = np.zeros(N_STATES, dtype=np.uint8)
        for state in range(N_STATES):
            self.dut.x.value = state
            self.dut.reflex_en.value = int(reflex[state])
            got[state] = await self.cycle()
        return got


def _difference(name, got, want) -> str:
    bad = np.flatnonzero(got != want)
    return f"{name}: {len(bad)} states differ, first {bad[0]}: HDL {got[bad[0]]}, reference {want[bad[0]]}"


@cocotb.test()
async def load_commit_all_shared_vectors(dut):
    tb = Testbench(dut)
    await tb.reset()
    names, pop = vectors.population()
    off, on = truth_tables(pop, reflex=False), truth_tables(pop, reflex=True)
    rng = np.random.default_rng(SEED)
    errors = []
    for g, rows in enumerate(pop):
        await tb.load(rows)
        reflex = rng.integers(0, 2, size=N_STATES).astype(bool)
        got = await tb.table(reflex)
        want = np.where(reflex, on[g], off[g])
        if not np.array_equal(got, want):
            errors.append(_difference(names[g], got, want))
    assert not errors, "\n".join(errors)
    dut._log.info("%d genomes x %d states match the reference", len(pop), N_STATES)


@cocotb.test()
async def half_written_shadow_never_reaches_motion(dut):
    tb = Testbench(dut)
    await tb.reset()
    names, pop = vectors.population()
    old, new = pop[names.index("minterms")], pop[names.index("random_30")]
    tt_old, tt_new = truth_tables(old, reflex=False), truth_tables(new, reflex=False)
    half = N_ROWS // 2
    tt_mixed = truth_tables(np.concatenate([new[:half], old[half:]]), reflex=False)
    assert not np.array_equal(tt_mixed, tt_old) and not np.array_equal(tt_mixed, tt_new)
    await tb.load(old)
    dut.reflex_en.value = 0
    for r in range(half):  # the robot keeps reading sensors while the host writes rows
        state = (r * 53 + 7) % N_STATES
        dut.x.value = state
        motion = await tb.write_row(r, new[r])
        assert motion == tt_old[state], f"row {r} written: state {state} gave {motion}, old {tt_old[state]}"
    assert np.array_equal(await tb.table(False), tt_old), "half-written shadow reached motion"
    await tb.commit()
    assert np.array_equal(await tb.table(False), tt_mixed)
    for r in range(half, N_ROWS - 1):
        await tb.write_row(r, new[r])
    await tb.write_row(N_ROWS - 1, new[-1], commit=True)  # the same-cycle write is committed
    assert np.array_equal(await tb.table(False), tt_new)


@cocotb.test()
async def reset_and_reflex(dut):
    tb = Testbench(dut)
    await tb.reset()
    assert not (await tb.table(False)).any(), "reset configuration is not all-zero"
    reflex = REFLEX_TABLE >= 0
    assert np.array_equal(await tb.table(True), np.where(reflex, REFLEX_TABLE, 0))
    five = vectors.edge_genomes()["empty_row_fires"]
    await tb.load(five)
    assert (await tb.table(False) == 5).all()
    assert np.array_equal(await tb.table(True), np.where(reflex, REFLEX_TABLE, 5))
    await tb.reset()
    assert dut.motion.value.to_unsigned() == 0
    await tb.commit()  # the shadow was cleared too
    assert not (await tb.table(False)).any()

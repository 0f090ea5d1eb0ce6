# amaranth: UnusedElaboratable=no
"""ControllerEHW (hdl/controller_ehw.py) in Amaranth's simulator and, via cocotb, in Icarus.

Loading row by row then committing, on every shared vector (tests/vectors.py), against the
reference truth tables with the reflex on and off; proof that a half-written shadow never reaches
``motion``; a write and a commit in the same cycle; the 1-cycle latency; synchronous reset.
The first line silences Amaranth's UnusedElaboratable warning for this file: the constructor
and port checks build components they never elaborate.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from amaranth.hdl import ClockDomain, Module
from amaranth.sim import Simulator

import vectors
from ga.genome import N_ROWS
from ga.motions import N_STATES, REFLEX_STATES, REFLEX_TABLE
from ga.truth_table import truth_tables
from hdl.controller_ehw import ControllerEHW
from hdl.ports import AmaranthPins, RowWriteSignature, write_rows

TB_DIR = Path(__file__).resolve().parent / "cocotb_tb"
STATES = np.arange(N_STATES)


class Bench:
    """Drives a ControllerEHW from an Amaranth testbench: the host's side of the board."""

    def __init__(self, ctx, dut: ControllerEHW, domain: ClockDomain):
        self.ctx, self.dut, self.domain = ctx, dut, domain
        self.pins = AmaranthPins(dut, ctx)

    async def write_row(self, addr: int, word: int, *, commit: bool = False):
        await write_rows(self.pins, "row", [word], strobe="commit" if commit else None, first_row=addr)

    async def commit(self):
        self.ctx.set(self.dut.commit, 1)
        await self.ctx.tick()
        self.ctx.set(self.dut.commit, 0)

    async def load(self, rows, *, commit: bool = True):
        await write_rows(self.pins, "row", rows)
        if commit:
            await self.commit()

    async def motion(self, state: int, reflex: bool = False) -> int:
        """Present ``state`` for one cycle; the registered motion for it appears after the edge."""
        self.ctx.set(self.dut.x, int(state))
        self.ctx.set(self.dut.reflex_en, int(reflex))
        await self.ctx.tick()
        return self.ctx.get(self.dut.motion)

    async def table(self, reflex: bool = False) -> np.ndarray:
        return np.array([await self.motion(s, reflex) for s in range(N_STATES)], dtype=np.uint8)

    async def reset(self):
        self.ctx.set(self.domain.rst, 1)
        await self.ctx.tick()
        self.ctx.set(self.domain.rst, 0)


def run_bench(body, dut: ControllerEHW | None = None):
    """Run ``async body(bench)`` against a fresh ControllerEHW with a clock and a reset we hold."""
    dut = dut or ControllerEHW()
    top = Module()
    top.domains.sync = domain = ClockDomain("sync")
    top.submodules.dut = dut

    async def testbench(ctx):
        await body(Bench(ctx, dut, domain))

    sim = Simulator(top)
    sim.add_clock(1e-6)
    sim.add_testbench(testbench)
    sim.run()


def _first_difference(name, got, want):
    bad = np.flatnonzero(got != want)
    return f"{name}: {len(bad)} states differ, first {bad[0]}: HDL {got[bad[0]]}, reference {want[bad[0]]}"


def test_load_then_commit_matches_reference_on_shared_vectors():
    """Every shared vector, loaded row by row and committed, over all 256 states; the reflex
    enable is a random bit per state (seeded) so both paths are checked in every genome."""
    names, pop = vectors.population()
    off, on = truth_tables(pop, reflex=False), truth_tables(pop, reflex=True)
    rng = np.random.default_rng(5)
    reflex_bits = rng.integers(0, 2, size=(len(pop), N_STATES)).astype(bool)
    reflex_bits[:, REFLEX_STATES] = rng.integers(0, 2, size=(len(pop), len(REFLEX_STATES))).astype(bool)
    errors = []

    async def body(bench):
        for g, rows in enumerate(pop):
            await bench.load(rows)
            got = np.array([await bench.motion(s, reflex_bits[g, s]) for s in STATES], dtype=np.uint8)
            want = np.where(reflex_bits[g], on[g], off[g])
            if not np.array_equal(got, want):
                errors.append(_first_difference(names[g], got, want))

    run_bench(body)
    assert not errors, "\n".join(errors)


def test_reflex_on_and_off():
    edges = vectors.edge_genomes()
    saturated = edges["empty_row_fires"]  # y = 5 everywhere without the reflex
    silent = edges["all_ones"]  # y = 0 everywhere without the reflex
    results = {}

    async def body(bench):
        await bench.load(saturated)
        results["sat_off"] = await bench.table(reflex=False)
        results["sat_on"] = await bench.table(reflex=True)
        await bench.load(silent)
        results["silent_on"] = await bench.table(reflex=True)

    run_bench(body)
    assert (results["sat_off"] == 5).all()
    reflex = REFLEX_TABLE >= 0
    assert np.array_equal(results["sat_on"][reflex], REFLEX_TABLE[reflex])
    assert (results["sat_on"][~reflex] == 5).all()
    assert np.array_equal(results["silent_on"], np.where(reflex, REFLEX_TABLE, 0))
    assert reflex.sum() == 4  # the 4 obstacle-free states, one per target sector


def test_half_written_shadow_never_reaches_motion():
    names, pop = vectors.population()
    old, new = pop[names.index("minterms")], pop[names.index("random_20")]
    tt_old, tt_new = truth_tables(old, reflex=False), truth_tables(new, reflex=False)
    half = N_ROWS // 2
    mixed = np.concatenate([new[:half], old[half:]])
    tt_mixed = truth_tables(mixed, reflex=False)
    assert not np.array_equal(tt_old, tt_new) and not np.array_equal(tt_mixed, tt_old)
    assert not np.array_equal(tt_mixed, tt_new)
    seen = {}

    async def body(bench):
        ctx, dut = bench.ctx, bench.dut
        await bench.load(old)
        # Write the first half of the new rows while the robot keeps reading sensors: each cycle
        # the motion must be the old controller's motion for the previous cycle's state.
        during = []
        prev_state = None
        for r in range(half):
            state = (r * 53 + 7) % N_STATES
            ctx.set(dut.x, state)
            ctx.set(dut.reflex_en, 0)
            await bench.write_row(r, new[r])
            during.append((state, ctx.get(dut.motion)))
            prev_state = state
        assert prev_state is not None
        seen["during"] = during
        seen["half_written"] = await bench.table()
        await bench.commit()
        seen["after_half_commit"] = await bench.table()
        for r in range(half, N_ROWS):
            await bench.write_row(r, new[r])
        seen["before_full_commit"] = await bench.table()
        await bench.commit()
        seen["after_full_commit"] = await bench.table()

    run_bench(body)
    for state, motion in seen["during"]:
        assert motion == tt_old[state], state
    assert np.array_equal(seen["half_written"], tt_old)
    assert np.array_equal(seen["after_half_commit"], tt_mixed)  # what was committed, no more
    assert np.array_equal(seen["before_full_commit"], tt_mixed)
    assert np.array_equal(seen["after_full_commit"], tt_new)


def test_write_and_commit_in_the_same_cycle_commit_includes_the_write():
    edges = vectors.edge_genomes()
    target = edges["single_literal_x0"]  # row 0: x0 -> y0
    seen = {}

    async def body(bench):
        for r in range(1, N_ROWS):
            await bench.write_row(r, target[r])
        await bench.write_row(0, target[0], commit=True)
        seen["table"] = await bench.table()

    run_bench(body)
    assert np.array_equal(seen["table"], truth_tables(target, reflex=False))


def test_commit_timing_and_motion_latency():
    """x in cycle t -> motion in cycle t + 1; commit in cycle t -> new motions from cycle t + 2."""
    five = vectors.edge_genomes()["empty_row_fires"]  # 5 everywhere
    trace = []

    async def body(bench):
        ctx, dut = bench.ctx, bench.dut
        await bench.load(five, commit=False)
        ctx.set(dut.x, 0b1)
        ctx.set(dut.reflex_en, 0)
        trace.append(ctx.get(dut.motion))  # cycle t: commit asserted now
        ctx.set(dut.commit, 1)
        await ctx.tick()
        ctx.set(dut.commit, 0)
        trace.append(ctx.get(dut.motion))  # cycle t + 1: still the old (all-zero) controller
        await ctx.tick()
        trace.append(ctx.get(dut.motion))  # cycle t + 2: the new controller
        # Latency: changing x does not change motion until the next edge.
        ctx.set(dut.x, 0)
        ctx.set(dut.reflex_en, 1)
        trace.append(ctx.get(dut.motion))
        await ctx.tick()
        trace.append(ctx.get(dut.motion))  # state 0, reflex on: sector front -> forward (0)

    run_bench(body)
    assert trace == [0, 0, 5, 5, int(REFLEX_TABLE[0])]


def test_synchronous_reset_clears_both_configurations():
    genome = vectors.edge_genomes()["empty_row_fires"]
    seen = {}

    async def body(bench):
        seen["initial_motion"] = bench.ctx.get(bench.dut.motion)
        seen["initial"] = await bench.table()
        await bench.load(genome)
        seen["loaded"] = await bench.table()
        bench.ctx.set(bench.dut.x, 0b1)
        await bench.reset()
        seen["motion_after_reset"] = bench.ctx.get(bench.dut.motion)
        seen["after_reset"] = await bench.table()
        await bench.commit()  # the shadow was cleared too
        seen["after_reset_commit"] = await bench.table()
        seen["after_reset_reflex"] = await bench.table(reflex=True)

    run_bench(body)
    assert seen["initial_motion"] == 0 and not seen["initial"].any()
    assert (seen["loaded"] == 5).all()
    assert seen["motion_after_reset"] == 0
    assert not seen["after_reset"].any() and not seen["after_reset_commit"].any()
    assert np.array_equal(seen["after_reset_reflex"], np.maximum(REFLEX_TABLE, 0))


def test_out_of_range_row_addresses_are_ignored():
    genome = vectors.edge_genomes()["single_literal"]
    seen = {}

    async def body(bench):
        await bench.load(genome)
        for addr in range(N_ROWS, 1 << len(bench.dut.row.addr)):
            await bench.write_row(addr, (1 << 19) - 1 if addr % 2 else 0b111 << 16)
        await bench.commit()
        seen["table"] = await bench.table()

    run_bench(body)
    assert np.array_equal(seen["table"], truth_tables(genome, reflex=False))


def test_ports_and_constructor():
    dut = ControllerEHW()
    widths = {name: len(getattr(dut, name)) for name in ("commit", "x", "reflex_en", "motion")}
    assert widths == dict(commit=1, x=8, reflex_en=1, motion=3)
    assert dut.signature.members["row"].signature == RowWriteSignature(N_ROWS).flip()
    assert [len(dut.row.addr), len(dut.row.data), len(dut.row.we)] == [6, 19, 1]
    assert len(ControllerEHW(k=4).row.addr) == 2
    for bad in (0, -3, 2.5, "50"):
        with pytest.raises((TypeError, ValueError), match=re.escape(f"k must be a positive integer, got {bad!r}")):
            ControllerEHW(k=bad)


def test_generated_verilog_ports(tmp_path):
    from hdl.generate import write_verilog

    text = write_verilog("controller_ehw", tmp_path).read_text()
    header = re.search(r"^module controller_ehw\((.*?)\);", text, re.S | re.M).group(1)
    assert sorted(p.strip() for p in header.split(",")) == sorted(
        ["clk", "rst", "row__addr", "row__data", "row__we", "commit", "x", "reflex_en", "motion"]
    )
    for decl in ("input [5:0] row__addr;", "input [18:0] row__data;", "input row__we;", "input commit;",
                 "input [7:0] x;", "input reflex_en;", "output [2:0] motion;", "input clk;", "input rst;"):
        assert decl in text, decl



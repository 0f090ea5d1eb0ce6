# amaranth: UnusedElaboratable=no
"""AndOrArray (hdl/and_or_array.py) against the reference model, three ways on the shared vectors.

(a) Amaranth's simulator, every one of the 256 inputs of every shared genome;
(b) cocotb on the generated Verilog in Icarus (tests/cocotb_tb/tb_and_or_array.py);
plus the Verilog port-list contract of SPEC section 8 and the constructor's checks.
(The reference against a naive model written from SPEC section 3 is in test_truth_table.py.)
The first line silences Amaranth's UnusedElaboratable warning for this file: the constructor
and port checks build components they never elaborate.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
import vectors
from amaranth.sim import Simulator

from ga.genome import GENOME_BITS, int_from_rows
from ga.motions import N_INPUTS, N_OUTPUTS, N_STATES
from ga.truth_table import truth_tables
from hdl.and_or_array import AndOrArray

TB_DIR = Path(__file__).resolve().parent / "cocotb_tb"


def simulate_truth_tables(dut: AndOrArray, population: np.ndarray) -> np.ndarray:
    """Drive ``arch`` with each genome and ``x`` with every state; read ``y``: (P, 2^n)."""
    out = np.zeros((len(population), 1 << dut.n), dtype=np.uint8)

    async def testbench(ctx):
        for g, rows in enumerate(population):
            ctx.set(dut.arch, int_from_rows(rows))
            for state in range(1 << dut.n):
                ctx.set(dut.x, state)  # combinational: a testbench's set settles before get
                out[g, state] = ctx.get(dut.y)

    sim = Simulator(dut)
    sim.add_testbench(testbench)
    sim.run()
    return out


def test_amaranth_sim_matches_reference_on_shared_vectors():
    names, pop = vectors.population()
    assert len(pop) >= 50 + len(vectors.edge_genomes())
    got = simulate_truth_tables(AndOrArray(), pop)
    want = truth_tables(pop, reflex=False)
    for g in np.flatnonzero((got != want).any(axis=1)):
        states = np.flatnonzero(got[g] != want[g])
        pytest.fail(
            f"{names[g]}: {len(states)} states differ, first state {states[0]}: "
            f"HDL {got[g, states[0]]}, reference {want[g, states[0]]}"
        )


def test_edge_genomes_have_the_expected_truth_tables():
    """The edge vectors really probe what their names say (so the comparisons above mean something)."""
    edges = vectors.edge_genomes()
    tt = {name: truth_tables(rows, reflex=False) for name, rows in edges.items()}
    states = np.arange(N_STATES)
    assert not tt["all_zeros"].any() and not tt["all_ones"].any()
    assert not tt["contradictory_rows"].any()
    assert (tt["empty_row_fires"] == 5).all() and (tt["empty_last_row"] == 4).all()
    assert np.array_equal(tt["single_literal"], ((states >> 3) & 1) * 2)
    assert np.array_equal(tt["single_not_literal"], 1 - ((states >> 7) & 1))
    assert np.array_equal(tt["contradiction_beside_valid"], (1 - ((states >> 5) & 1)) * 2)
    assert (tt["minterms"] != 0).sum() == 50


def test_random_vectors_vary_in_density():
    """The random genomes span near-empty to saturated truth tables."""
    tables = truth_tables(vectors.random_genomes(), reflex=False)
    nonzero = (tables != 0).mean(axis=1)
    saturated = (tables == 7).mean(axis=1)
    assert nonzero.min() < 0.2 and saturated.max() > 0.9
    assert len(np.unique(nonzero.round(1))) >= 5


@pytest.mark.parametrize("kwargs", [dict(n=2, m=1, k=3), dict(n=3, m=2, k=5)])
def test_small_parametrised_arrays_match_a_plain_model(kwargs):
    """n, m, k other than 8, 3, 50 follow the same row layout (W = 2n + m), exhaustively."""
    dut = AndOrArray(**kwargs)
    n, m, k = dut.n, dut.m, dut.k
    W = 2 * n + m
    rng = np.random.default_rng(7)
    archs = [0, (1 << (k * W)) - 1] + [int(v) for v in rng.integers(0, 1 << min(k * W, 62), size=40)]
    got = {}

    async def testbench(ctx):
        for arch in archs:
            ctx.set(dut.arch, arch)
            for x in range(1 << n):
                ctx.set(dut.x, x)
                got[arch, x] = ctx.get(dut.y)

    sim = Simulator(dut)
    sim.add_testbench(testbench)
    sim.run()
    for (arch, x), y in got.items():
        want = 0
        for r in range(k):
            row = arch >> (r * W)
            fires = all(
                not (row >> (2 * i) & 1 and not x >> i & 1) and not (row >> (2 * i + 1) & 1 and x >> i & 1)
                for i in range(n)
            )
            if fires:
                want |= (row >> (2 * n)) & ((1 << m) - 1)
        assert y == want, (kwargs, hex(arch), x)


@pytest.mark.parametrize("bad", [0, -1, 2.0, "8", True, None])
def test_constructor_rejects_bad_parameters(bad):
    for name in ("n", "m", "k"):
        with pytest.raises((TypeError, ValueError), match=f"{name} must be a positive integer, got {bad!r}"):
            AndOrArray(**{name: bad})


def test_ports_and_widths():
    dut = AndOrArray()
    assert (dut.n, dut.m, dut.k, dut.row_bits) == (N_INPUTS, N_OUTPUTS, 50, 19)
    assert len(dut.arch) == GENOME_BITS and len(dut.x) == 8 and len(dut.y) == 3
    assert AndOrArray(n=4, m=2, k=7).arch.shape().width == 7 * 10


def _ports(verilog: str, module: str) -> dict[str, tuple[str, int]]:
    """{port: (direction, width)} of ``module`` from its header and input/output declarations."""
    body = re.search(rf"^module {module}\((.*?)\);(.*?)^endmodule", verilog, re.S | re.M)
    assert body, f"module {module} not found"
    header = [p.strip() for p in body.group(1).split(",")]
    decls = {}
    for direction, msb, lsb, name in re.findall(
        r"^\s*(input|output|inout)\s+(?:wire\s+|reg\s+)?(?:\[(\d+):(\d+)\]\s*)?\\?(\w+)\s*;", body.group(2), re.M
    ):
        decls[name] = (direction, int(msb) - int(lsb) + 1 if msb else 1)
    assert sorted(header) == sorted(decls), (header, decls)
    return decls


def test_generated_verilog_has_exactly_the_contract_ports(tmp_path):
    from cosim.cli.main import main

    assert main(["verilog", "--out", str(tmp_path), "and_or_array"]) == 0  # what `make verilog` runs
    path = tmp_path / "and_or_array.v"
    text = path.read_text()
    assert _ports(text, "and_or_array") == {
        "arch": ("input", GENOME_BITS),
        "x": ("input", 8),
        "y": ("output", 3),
    }
    assert "[949:0] arch" in text
    assert not re.search(r"\b(clk|rst)\b", text)


@pytest.mark.cocotb
def test_plain_verilog_testbench_instantiates_by_port_names(tmp_path):
    """An outside Verilog testbench (no cocotb) instantiates ``and_or_array`` by the contract
    port names and sweeps all 256 inputs of a few shared vectors in Icarus."""
    import shutil
    import subprocess

    from hdl.generate import write_verilog

    if shutil.which("iverilog") is None:
        pytest.fail("iverilog is not on PATH: run 'make test' (it installs it) or apt-get install iverilog")
    names, pop = vectors.population()
    picks = [names.index(n) for n in ("single_literal", "minterms", "random_05", "random_40")]
    src = write_verilog("and_or_array", tmp_path)
    lines = ["`timescale 1ns/1ps", "module tb;", "  reg [949:0] arch; reg [7:0] x; wire [2:0] y;",
             "  integer s;", "  and_or_array dut(.arch(arch), .x(x), .y(y));", "  initial begin"]
    for g in picks:
        lines.append(f"    arch = 950'h{int_from_rows(pop[g]):x};")
        lines.append('    for (s = 0; s < 256; s = s + 1) begin x = s; #1 $write("%0d", y); end')
        lines.append('    $write("\\n");')
    lines += ["    $finish;", "  end", "endmodule"]
    tb = tmp_path / "tb.v"
    tb.write_text("\n".join(lines) + "\n")
    exe = tmp_path / "tb.vvp"
    subprocess.run(["iverilog", "-g2012", "-o", str(exe), str(tb), str(src)], check=True)
    out = subprocess.run(["vvp", "-n", str(exe)], check=True, capture_output=True, text=True).stdout
    got = [line for line in out.splitlines() if len(line) == 256]
    want = ["".join(map(str, truth_tables(pop[g], reflex=False))) for g in picks]
    assert got == want

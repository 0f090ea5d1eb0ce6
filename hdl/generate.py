"""Verilog generation for every EHW block: ``make verilog`` -> build/verilog/*.v.

Module and file names are part of the contract (SPEC section 8): ``and_or_array`` has exactly the
ports ``arch[949:0]``, ``x[7:0]``, ``y[2:0]`` and no clock.
"""

from __future__ import annotations

import argparse
import importlib
import re
from pathlib import Path

from amaranth.back import verilog

from base.files import atomic_write_text

# (file stem = Verilog module name, "module:factory") -- the factory takes no argument.
BLOCKS = {
    "and_or_array": "hdl.and_or_array:AndOrArray",
    "controller_ehw": "hdl.controller_ehw:ControllerEHW",
    "evaluator_ehw": "hdl.evaluator_ehw:EvaluatorEHW",
    "system_top": "hdl.system_top:SystemTop",
}


# Yosys's Verilog makes every ``always @*`` block also read a 1-bit ``reg ... = 0`` so that it runs
# at time 0. A simulator that applies that initialiser without an event (Icarus in its SystemVerilog
# mode, -g2012, as cocotb runs it) never evaluates a combinational block whose inputs keep their
# initial values, and the block drives X until one changes (seen: the evaluator's per-motion
# distance lookup read X while ``cur_motion`` stayed 0). A non-blocking 1 at time 0 updates after
# every process has reached its first wait, so each such block runs once. Verilator evaluates all
# combinational logic at start-up and would warn (INITIALDLY) on the assignment: it skips the line.
# No delay (``#1``): Verilator refuses delays without a --timing option.
_TRIGGER = re.compile(r"^(\s*)reg (\\\$auto\$verilog_backend\.cc:\d+:dump_module\$\d+ ) = 0;$", re.M)


def time_zero_fix(verilog: str) -> str:
    """``verilog`` with each of Yosys's time-0 trigger registers set once at time 0 (see above),
    so that it simulates from reset in Icarus (-g2005 or -g2012) and Verilator as it is."""
    return _TRIGGER.sub(
        lambda mt: f"{mt.group(0)}\n`ifndef VERILATOR\n{mt.group(1)}initial {mt.group(2)}<= 1'b1;\n`endif",
        verilog)


def convert(component, name: str) -> str:
    """Amaranth's Verilog of ``component`` (top module ``name``), with the time-0 fix: what every
    Verilog file of this project is made with."""
    return time_zero_fix(verilog.convert(component, name=name, emit_src=False))


def build_block(name: str):
    module_name, factory = BLOCKS[name].split(":")
    return getattr(importlib.import_module(module_name), factory)()


def verilog_text(name: str) -> str:
    """The Verilog of block ``name``, its top module named ``name``."""
    if name not in BLOCKS:
        raise KeyError(f"unknown block {name!r}; known: {sorted(BLOCKS)}")
    return convert(build_block(name), name)


def write_verilog(name: str, out_dir: Path | str = "build/verilog") -> Path:
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    path = out / f"{name}.v"
    atomic_write_text(path, verilog_text(name))
    return path


def add_arguments(parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
    parser.add_argument("--out", default="build/verilog", metavar="DIR", help="output folder")
    parser.add_argument("blocks", nargs="*", default=list(BLOCKS), metavar="BLOCK",
                        help=f"blocks to generate (default: all of {', '.join(BLOCKS)})")
    return parser


def run_from_args(args) -> int:
    from base.errors import UserError

    unknown = [b for b in args.blocks if b not in BLOCKS]
    if unknown:
        raise UserError(f"unknown block(s) {unknown}; known: {', '.join(BLOCKS)}")
    for name in args.blocks:
        print(write_verilog(name, args.out))
    return 0


if __name__ == "__main__":  # the module alone; ``ehw verilog`` adds the input checks and the lock
    import argparse

    raise SystemExit(run_from_args(add_arguments(argparse.ArgumentParser(prog="python -m hdl.generate")).parse_args()))

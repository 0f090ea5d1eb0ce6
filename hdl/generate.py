"""Verilog generation for every EHW block: ``make verilog`` -> build/verilog/*.v.

Module and file names are part of the contract (SPEC section 8): ``and_or_array`` has exactly the
ports ``arch[949:0]``, ``x[7:0]``, ``y[2:0]`` and no clock.
"""

from __future__ import annotations

import argparse
import importlib
from pathlib import Path

from amaranth.back import verilog

# (file stem = Verilog module name, "module:factory") -- the factory takes no argument.
BLOCKS = {
    "and_or_array": "hdl.and_or_array:AndOrArray",
    "controller_ehw": "hdl.controller_ehw:ControllerEHW",
    "evaluator_ehw": "hdl.evaluator_ehw:EvaluatorEHW",
    "system_top": "hdl.system_top:SystemTop",
}


def build_block(name: str):
    module_name, factory = BLOCKS[name].split(":")
    return getattr(importlib.import_module(module_name), factory)()


def verilog_text(name: str) -> str:
    """The Verilog of block ``name``, its top module named ``name``."""
    if name not in BLOCKS:
        raise KeyError(f"unknown block {name!r}; known: {sorted(BLOCKS)}")
    component = build_block(name)
    return verilog.convert(component, name=name, emit_src=False)


def write_verilog(name: str, out_dir: Path | str = "build/verilog") -> Path:
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    path = out / f"{name}.v"
    path.write_text(verilog_text(name))
    return path


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="build/verilog", help="output folder (default %(default)s)")
    parser.add_argument("blocks", nargs="*", default=list(BLOCKS), help="blocks to generate (default: all)")
    args = parser.parse_args(argv)
    for name in args.blocks:
        print(write_verilog(name, args.out))


if __name__ == "__main__":
    main()

"""The cocotb testbenches of the single blocks (tests/cocotb_tb/tb_<block>.py), each on the
generated Verilog of its block in Icarus: one parametrised runner for all of them.

Each bench must run exactly the tests it declares (a bench that silently stops running one
fails here); the benches compare the HDL with the NumPy reference on the shared vectors.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

TB_DIR = Path(__file__).resolve().parent / "cocotb_tb"
BLOCKS = ("and_or_array", "controller_ehw", "evaluator_ehw")


def declared_tests(block: str) -> int:
    """The ``@cocotb.test`` coroutines of ``tb_<block>.py`` (cocotb counts a skipped one too)."""
    text = (TB_DIR / f"tb_{block}.py").read_text()
    return len(re.findall(r"^@cocotb\.test\(", text, re.M))


@pytest.mark.cocotb
@pytest.mark.parametrize("block", BLOCKS)
def test_cocotb_bench(block, tmp_path):
    from cosim.boards.cocotb_run import run_cocotb
    from hdl.generate import write_verilog

    src = write_verilog(block, tmp_path)
    n_tests, _ = run_cocotb(sources=[src], toplevel=block, test_module=f"tb_{block}",
                            test_dir=TB_DIR, build_name=block)
    assert declared_tests(block) >= 1
    assert n_tests == declared_tests(block)

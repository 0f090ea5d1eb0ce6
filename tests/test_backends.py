"""The three board backends (SPEC section 9): the system top under cocotb on the shared cases, and
the short on-line run that must be identical in every backend."""

from __future__ import annotations

from pathlib import Path

import pytest

TB_DIR = Path(__file__).resolve().parent / "cocotb_tb"

pytestmark = pytest.mark.filterwarnings("ignore::amaranth.hdl.UnusedElaboratable")


@pytest.mark.cocotb
def test_cocotb_system_top_matches_reference(tmp_path):
    from cosim.cocotb_run import run_cocotb
    from cosim.cocotb_backend import write_system_verilog

    src = write_system_verilog(tmp_path)
    n_tests, _ = run_cocotb(sources=[src], toplevel="system_top", test_module="tb_system",
                            test_dir=TB_DIR, build_name="system_top_tb")
    assert n_tests == 3

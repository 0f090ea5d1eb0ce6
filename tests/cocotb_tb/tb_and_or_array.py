"""cocotb testbench: the generated and_or_array Verilog against the NumPy reference.

Every one of the 256 inputs of every shared vector (tests/vectors.py), one Timer step each.
Started from pytest by tests/test_and_or_array.py through cosim.boards.cocotb_run.run_cocotb.
"""

from __future__ import annotations

import sys
from pathlib import Path

import cocotb
import numpy as np
from cocotb.triggers import Timer

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # tests/, for vectors

import vectors  # noqa: E402

from ga.genome import int_from_rows  # noqa: E402
from ga.motions import N_STATES  # noqa: E402
from ga.truth_table import truth_tables  # noqa: E402


@cocotb.test()
async def all_inputs_of_shared_vectors(dut):
    names, pop = vectors.population()
    want = truth_tables(pop, reflex=False)
    errors = []
    for g, rows in enumerate(pop):
        dut.arch.value = int_from_rows(rows)
        got = np.zeros(N_STATES, dtype=np.uint8)
        for state in range(N_STATES):
            dut.x.value = state
            await Timer(1, unit="ns")
            got[state] = dut.y.value.to_unsigned()
        bad = np.flatnonzero(got != want[g])
        if len(bad):
            errors.append(f"{names[g]}: {len(bad)} states differ, first {bad[0]}: "
                          f"HDL {got[bad[0]]}, reference {want[g, bad[0]]}")
    assert not errors, "\n".join(errors)
    dut._log.info("%d genomes x %d inputs match the reference", len(pop), N_STATES)

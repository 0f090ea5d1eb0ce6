"""The reference model (ga/truth_table.py) against a deliberately naive model written from SPEC
sections 3 and 6, on the shared vectors (tests/vectors.py) and on hypothesis genomes; the reflex
on and off; motion_of against truth_tables; shapes and errors.

The naive model reads the genome as the 950-bit integer of SPEC section 3 and indexes its bits
exactly as the SPEC text words them (row r at bits [19r, 19r + 19), bit 2i: x_i, 2i + 1: NOT x_i,
16 + j: drives y_j); it uses none of ga.genome's or ga.motions' helpers, and re-types the reflex
from SPEC section 6 on purpose, as an independent check of ga.motions.REFLEX_TABLE.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import vectors
from ga.genome import GenomeError, int_from_rows, rows_from_int
from ga.motions import REFLEX_MOTION, REFLEX_STATES, REFLEX_TABLE, Motion
from ga.truth_table import motion_of, truth_tables, truth_tables_python

# SPEC section 6, typed from its text: sector front -> forward, left -> turn left,
# back -> turn left, right -> turn right (sector code x6 + 2*x7; motion codes of section 4).
SPEC_REFLEX = {0: 0, 1: 2, 2: 2, 3: 3}


def spec_integer(rows) -> int:
    """The genome integer from its 50 row words: row r at bits [19r, 19r + 19) (SPEC section 3)."""
    return sum(int(word) << (19 * r) for r, word in enumerate(rows))


def naive_truth_table(genome: int, reflex: bool) -> list[int]:
    """Motion of every state, straight from SPEC sections 3 and 6: one bit at a time."""
    bit = [(genome >> b) & 1 for b in range(950)]
    table = []
    for state in range(256):
        x = [(state >> i) & 1 for i in range(8)]
        if reflex and all(x[i] == 0 for i in range(6)):
            table.append(SPEC_REFLEX[x[6] + 2 * x[7]])
            continue
        y = [0, 0, 0]
        for r in range(50):
            base = 19 * r
            fires = True  # a row with no connected literal fires always
            for i in range(8):
                if bit[base + 2 * i] == 1 and x[i] == 0:  # x_i connected but false
                    fires = False
                if bit[base + 2 * i + 1] == 1 and x[i] == 1:  # NOT x_i connected but false
                    fires = False
            if fires:
                for j in range(3):
                    if bit[base + 16 + j] == 1:
                        y[j] = 1
        table.append(y[0] + 2 * y[1] + 4 * y[2])
    return table


def test_reference_matches_naive_model_on_shared_vectors():
    names, pop = vectors.population()
    assert len(pop) >= 50 + len(vectors.edge_genomes())
    off, on = truth_tables(pop, reflex=False), truth_tables(pop, reflex=True)
    for g, rows in enumerate(pop):
        genome = spec_integer(rows)
        assert genome == int_from_rows(rows), names[g]
        assert off[g].tolist() == naive_truth_table(genome, reflex=False), names[g]
        # With the reflex, only the 4 obstacle-free states can differ from the array alone.
        want_on = off[g].copy()
        for state, motion in SPEC_REFLEX.items():
            want_on[state << 6] = motion
        assert np.array_equal(on[g], want_on), names[g]


@given(st.integers(min_value=0, max_value=(1 << 950) - 1), st.booleans())
def test_reference_matches_naive_model_on_hypothesis_genomes(genome, reflex):
    rows = rows_from_int(genome)
    assert truth_tables(rows, reflex=reflex).tolist() == naive_truth_table(genome, reflex)


def test_reflex_table_agrees_with_spec_text():
    assert sorted(REFLEX_STATES.tolist()) == [0, 64, 128, 192]
    assert {int(s) >> 6: int(REFLEX_TABLE[s]) for s in REFLEX_STATES} == SPEC_REFLEX
    assert (REFLEX_TABLE >= 0).sum() == 4
    assert [Motion(int(m)).name for m in REFLEX_MOTION] == ["FORWARD", "TURN_LEFT", "TURN_LEFT", "TURN_RIGHT"]


def test_reflex_on_changes_only_obstacle_free_states():
    _, pop = vectors.population()
    off, on = truth_tables(pop, reflex=False), truth_tables(pop, reflex=True)
    free = np.zeros(256, dtype=bool)
    free[REFLEX_STATES] = True
    assert np.array_equal(on[:, ~free], off[:, ~free])
    assert (on[:, free] == REFLEX_TABLE[free]).all()
    assert (off[:, free] != on[:, free]).any()  # the vectors do exercise the override


def test_truth_tables_default_is_reflex_on():
    _, pop = vectors.population()
    assert np.array_equal(truth_tables(pop), truth_tables(pop, reflex=True))


@pytest.mark.parametrize("reflex", [False, True])
def test_motion_of_agrees_with_truth_tables(reflex):
    names, pop = vectors.population()
    tables = truth_tables(pop, reflex=reflex)
    for g in range(0, len(pop), 5):
        assert [motion_of(pop[g], s, reflex) for s in range(256)] == tables[g].tolist(), names[g]


def test_python_baseline_agrees():
    _, pop = vectors.population()
    few = pop[::12]
    for reflex in (False, True):
        assert np.array_equal(np.array(truth_tables_python(few, reflex), dtype=np.uint8), truth_tables(few, reflex))


def test_shapes_and_dtype():
    _, pop = vectors.population()
    assert truth_tables(pop).shape == (len(pop), 256) and truth_tables(pop).dtype == np.uint8
    assert truth_tables(pop[3]).shape == (256,)
    assert np.array_equal(truth_tables(pop[3]), truth_tables(pop[3:4])[0])
    assert truth_tables(np.zeros((0, 50), dtype=np.uint32)).shape == (0, 256)
    assert np.array_equal(truth_tables(pop.tolist()), truth_tables(pop))  # plain lists are fine


def test_bad_input_is_rejected():
    with pytest.raises(GenomeError, match="shape"):
        truth_tables(np.zeros((3, 49), dtype=np.uint32))
    with pytest.raises(GenomeError, match="does not fit"):
        truth_tables(np.full(50, 1 << 19))
    with pytest.raises(GenomeError, match="does not fit"):
        truth_tables(np.full(50, -1))
    with pytest.raises(ValueError, match="256"):
        motion_of(np.zeros(50, dtype=np.uint32), 256)
    with pytest.raises(ValueError, match="-1"):
        motion_of(np.zeros(50, dtype=np.uint32), -1)
    with pytest.raises(ValueError, match="one genome"):
        motion_of(np.zeros((2, 50), dtype=np.uint32), 0)

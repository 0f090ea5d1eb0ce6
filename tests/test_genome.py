"""The genome contract (ga/genome.py, SPEC section 3): conversions between the integer, the
238-digit hex text, the 950-bit array and the 50 row words, and clear errors for bad input."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from ga.genome import (
    GENOME_BITS,
    HEX_DIGITS,
    N_ROWS,
    ROW_BITS,
    ROW_MASK,
    Genome,
    GenomeError,
    bits_from_rows,
    hex_from_rows,
    int_from_rows,
    rows_from_bits,
    rows_from_hex,
    rows_from_int,
    validate_rows,
)

genome_ints = st.integers(min_value=0, max_value=(1 << GENOME_BITS) - 1)
row_words = st.lists(st.integers(min_value=0, max_value=ROW_MASK), min_size=N_ROWS, max_size=N_ROWS)


def test_constants_follow_spec_section_3():
    assert (N_ROWS, ROW_BITS, GENOME_BITS, HEX_DIGITS) == (50, 19, 950, 238)


@given(genome_ints)
def test_int_rows_round_trip_and_layout(value):
    rows = rows_from_int(value)
    assert rows.shape == (N_ROWS,) and rows.dtype == np.uint32
    assert int_from_rows(rows) == value
    for r in (0, 1, 17, N_ROWS - 1):  # row r holds genome bits [19r, 19r + 19)
        assert int(rows[r]) == (value >> (ROW_BITS * r)) & ROW_MASK


@given(genome_ints)
def test_hex_round_trip(value):
    text = hex_from_rows(rows_from_int(value))
    assert len(text) == HEX_DIGITS and text == text.lower()
    assert int(text, 16) == value
    assert np.array_equal(rows_from_hex(text), rows_from_int(value))
    # Upper case, a 0x prefix and surrounding white space are accepted.
    assert np.array_equal(rows_from_hex(f"  0X{text.upper()}\n"), rows_from_int(value))


@given(genome_ints)
def test_bits_round_trip_lsb_first(value):
    rows = rows_from_int(value)
    bits = bits_from_rows(rows)
    assert bits.shape == (GENOME_BITS,) and bits.dtype == np.uint8
    assert bits.tolist() == [(value >> b) & 1 for b in range(GENOME_BITS)]
    assert np.array_equal(rows_from_bits(bits), rows)
    assert np.array_equal(rows_from_bits(bits.astype(bool)), rows)


@given(st.lists(row_words, min_size=0, max_size=6))
def test_population_round_trips(pop):
    pop = np.array(pop, dtype=np.uint32).reshape(len(pop), N_ROWS)
    bits = bits_from_rows(pop)
    assert bits.shape == (len(pop), GENOME_BITS)
    assert np.array_equal(rows_from_bits(bits), pop)
    for g in range(len(pop)):
        assert np.array_equal(bits[g], bits_from_rows(pop[g]))
        assert np.array_equal(rows_from_hex(hex_from_rows(pop[g])), pop[g])


@given(row_words)
def test_genome_object_round_trips(words):
    genome = Genome(np.array(words))
    assert Genome.from_int(genome.to_int()) == genome
    assert Genome.from_hex(genome.to_hex()) == genome
    assert Genome.from_bits(genome.to_bits()) == genome
    assert hash(Genome.from_hex(genome.to_hex())) == hash(genome)
    assert eval(repr(genome), {"Genome": Genome}) == genome


def test_genome_is_immutable_and_copies_its_input():
    words = np.arange(N_ROWS, dtype=np.uint32)
    genome = Genome(words)
    words[0] = 99
    assert genome.rows[0] == 0
    with pytest.raises(ValueError):
        genome.rows[1] = 5
    assert genome != Genome(np.zeros(N_ROWS, dtype=np.uint32)) and genome != "not a genome"


def test_validate_rows_accepts_any_integer_dtype():
    for dtype in (np.uint8, np.int16, np.int64, np.uint64):
        assert validate_rows(np.ones(N_ROWS, dtype=dtype)).dtype == np.uint32
    assert validate_rows(list(range(N_ROWS))).tolist() == list(range(N_ROWS))


# -- bad input: a clear error, never a silent truncation -------------------------------------

@pytest.mark.parametrize("digits", [0, 1, HEX_DIGITS - 1, HEX_DIGITS + 1, 2 * HEX_DIGITS])
def test_hex_of_wrong_length_is_rejected(digits):
    with pytest.raises(GenomeError, match=f"exactly {HEX_DIGITS} hex digits, got {digits}"):
        rows_from_hex("1" * digits)


@pytest.mark.parametrize("bad", ["g", "-", " ", "_", "é"])
def test_non_hex_text_is_rejected(bad):
    text = "0" * 100 + bad + "0" * (HEX_DIGITS - 101)
    with pytest.raises(GenomeError, match=f"hexadecimal, found {bad!r}"):
        rows_from_hex(text)


def test_hex_with_bits_beyond_950_is_rejected():
    # 238 digits hold 952 bits: the top two must be zero.
    with pytest.raises(GenomeError, match="950"):
        rows_from_hex("4" + "0" * (HEX_DIGITS - 1))
    assert rows_from_hex("3" + "f" * (HEX_DIGITS - 1)).tolist() == [ROW_MASK] * N_ROWS


@pytest.mark.parametrize("bad", [b"00", 12, None, ["0"]])
def test_hex_of_wrong_type_is_rejected(bad):
    with pytest.raises(GenomeError, match="must be a str"):
        rows_from_hex(bad)


@pytest.mark.parametrize("value", [-1, -(1 << 949), 1 << GENOME_BITS, (1 << GENOME_BITS) + 5, 1 << 2000])
def test_out_of_range_integers_are_rejected(value):
    with pytest.raises(GenomeError, match=r"\[0, 2\*\*950\)"):
        rows_from_int(value)


@pytest.mark.parametrize("value", [1.0, "5", True, None, np.float64(3)])
def test_non_integer_genome_values_are_rejected(value):
    with pytest.raises(GenomeError, match="must be an int"):
        rows_from_int(value)


@pytest.mark.parametrize("word", [1 << ROW_BITS, ROW_MASK + 1000, -1, 1 << 40])
def test_out_of_range_rows_are_rejected_naming_the_row(word):
    rows = np.zeros(N_ROWS, dtype=np.int64)
    rows[7] = word
    with pytest.raises(GenomeError, match=rf"{word}.*index \(7,\).*19 bits"):
        validate_rows(rows)
    pop = np.zeros((3, N_ROWS), dtype=np.int64)
    pop[2, 4] = word
    with pytest.raises(GenomeError, match=r"index \(2, 4\)"):
        validate_rows(pop)


@pytest.mark.parametrize("shape", [(), (N_ROWS - 1,), (N_ROWS + 1,), (N_ROWS, 1), (2, 3, N_ROWS), (0,)])
def test_wrong_row_shapes_are_rejected(shape):
    with pytest.raises(GenomeError, match="shape"):
        validate_rows(np.zeros(shape, dtype=np.uint32))


def test_non_integer_rows_are_rejected():
    with pytest.raises(GenomeError, match="integers"):
        validate_rows(np.zeros(N_ROWS, dtype=np.float64))
    with pytest.raises(GenomeError, match="integers"):
        validate_rows([1 << 70] * N_ROWS)  # too big for any integer dtype


def test_one_genome_functions_reject_populations():
    pop = np.zeros((2, N_ROWS), dtype=np.uint32)
    with pytest.raises(GenomeError, match="one genome"):
        int_from_rows(pop)
    with pytest.raises(GenomeError, match="one genome"):
        hex_from_rows(pop)
    with pytest.raises(GenomeError, match="one genome"):
        Genome(pop)


@pytest.mark.parametrize("shape", [(GENOME_BITS - 1,), (GENOME_BITS + 1,), (2, 3, GENOME_BITS), ()])
def test_bits_of_wrong_shape_are_rejected(shape):
    with pytest.raises(GenomeError, match="950 bits"):
        rows_from_bits(np.zeros(shape, dtype=np.uint8))


@pytest.mark.parametrize("bad", [2, -1, 255])
def test_bits_other_than_0_1_are_rejected(bad):
    bits = np.zeros(GENOME_BITS, dtype=np.int64)
    bits[100] = bad
    with pytest.raises(GenomeError, match="0 or 1"):
        rows_from_bits(bits)

"""The 950 architecture bits of the AND-OR array: the genome contract of SPEC section 3.

Layout (normative): row r of k = 50 occupies genome bits [19r, 19r + 19). Inside a row, bit 2i
connects literal x_i, bit 2i + 1 connects NOT x_i (i = 0..7), and bit 16 + j makes the row drive
output y_j (j = 0..2). Genome bit b is bit b of an unsigned integer, LSB first; its text form is
that integer as 238 lower-case hex digits.

The canonical in-memory form is the *rows* form: a ``numpy.uint32`` array of shape (50,) for one
genome, (P, 50) for a population, each entry a 19-bit row word with bit c at position c (the word
the HDL's row-write port takes). Every other form converts through it.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from ga.motions import N_INPUTS, N_OUTPUTS

N_ROWS = 50  # k
LITERAL_BITS = 2 * N_INPUTS  # 16: the AND plane of one row
ROW_BITS = LITERAL_BITS + N_OUTPUTS  # 19
GENOME_BITS = N_ROWS * ROW_BITS  # 950
HEX_DIGITS = (GENOME_BITS + 3) // 4  # 238
ROW_MASK = (1 << ROW_BITS) - 1
LITERAL_MASK = (1 << LITERAL_BITS) - 1
OUTPUT_SHIFT = LITERAL_BITS
OUTPUT_MASK = ((1 << N_OUTPUTS) - 1) << OUTPUT_SHIFT
ROW_DTYPE = np.uint32

_HEX_RE = re.compile(r"[0-9a-fA-F]+")


class GenomeError(ValueError):
    """A genome in any form that does not satisfy SPEC section 3."""


def validate_rows(rows) -> np.ndarray:
    """Check a genome (50,) or population (P, 50) of row words; return it as uint32.

    Rejects wrong shapes, negative or non-integer entries and words wider than 19 bits, naming the
    first offending row. Never truncates.
    """
    arr = np.asarray(rows)
    if arr.ndim not in (1, 2) or arr.shape[-1] != N_ROWS:
        raise GenomeError(f"expected {N_ROWS} row words per genome, got an array of shape {arr.shape!r}")
    if arr.size and not np.issubdtype(arr.dtype, np.integer):
        raise GenomeError(f"row words must be integers, got dtype {arr.dtype!r}")
    if arr.size:
        bad = (arr.astype(np.int64) < 0) | (arr.astype(np.int64) > ROW_MASK)
        if bad.any():
            where = tuple(int(i) for i in np.argwhere(bad)[0])
            raise GenomeError(
                f"row word {arr[where]!r} at index {where!r} does not fit in {ROW_BITS} bits"
            )
    return arr.astype(ROW_DTYPE, copy=False)


def rows_from_int(value: int) -> np.ndarray:
    """The 50 row words of the genome whose 950 bits are the integer ``value``."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise GenomeError(f"a genome integer must be an int, got {value!r}")
    value = int(value)
    if value < 0 or value.bit_length() > GENOME_BITS:
        raise GenomeError(
            f"a genome integer must be in [0, 2**{GENOME_BITS}), got one of {value.bit_length()} bits"
        )
    return np.array([(value >> (ROW_BITS * r)) & ROW_MASK for r in range(N_ROWS)], dtype=ROW_DTYPE)


def int_from_rows(rows) -> int:
    """The 950-bit integer of one genome in rows form."""
    rows = validate_rows(rows)
    if rows.ndim != 1:
        raise GenomeError(f"expected one genome of shape ({N_ROWS},), got {rows.shape!r}")
    value = 0
    for r in range(N_ROWS - 1, -1, -1):
        value = (value << ROW_BITS) | int(rows[r])
    return value


def rows_from_hex(text: str) -> np.ndarray:
    """Parse the 238-digit hex text form (surrounding white space and a 0x prefix are allowed)."""
    if not isinstance(text, str):
        raise GenomeError(f"a genome text must be a str, got {type(text).__name__}")
    digits = text.strip()
    if digits[:2].lower() == "0x":
        digits = digits[2:]
    if len(digits) != HEX_DIGITS:
        raise GenomeError(f"a genome text has exactly {HEX_DIGITS} hex digits, got {len(digits)}")
    if not _HEX_RE.fullmatch(digits):
        bad = next(c for c in digits if c not in "0123456789abcdefABCDEF")
        raise GenomeError(f"a genome text must be hexadecimal, found {bad!r}")
    return rows_from_int(int(digits, 16))


def hex_from_rows(rows) -> str:
    """The 238-digit lower-case hex text of one genome."""
    return format(int_from_rows(rows), f"0{HEX_DIGITS}x")


def bits_from_rows(rows) -> np.ndarray:
    """Genome bits as a uint8 array: (950,) for one genome, (P, 950) for a population."""
    rows = validate_rows(rows)
    shifts = np.arange(ROW_BITS, dtype=ROW_DTYPE)
    bits = (rows[..., None] >> shifts) & 1  # (..., 50, 19)
    return bits.reshape(*rows.shape[:-1], GENOME_BITS).astype(np.uint8)


def rows_from_bits(bits) -> np.ndarray:
    """Row words from a (950,) or (P, 950) array of 0/1 bits (anything else is an error)."""
    arr = np.asarray(bits)
    if arr.ndim not in (1, 2) or arr.shape[-1] != GENOME_BITS:
        raise GenomeError(f"expected {GENOME_BITS} bits per genome, got an array of shape {arr.shape!r}")
    if arr.size and not np.isin(arr, (0, 1)).all():
        raise GenomeError("genome bits must be 0 or 1")
    grouped = arr.astype(ROW_DTYPE).reshape(*arr.shape[:-1], N_ROWS, ROW_BITS)
    return (grouped << np.arange(ROW_BITS, dtype=ROW_DTYPE)).sum(axis=-1, dtype=ROW_DTYPE)


@dataclass(frozen=True, eq=False)
class Genome:
    """One controller: 50 row words, immutable. Build it from any of the four forms."""

    rows: np.ndarray

    def __post_init__(self):
        rows = validate_rows(self.rows)
        if rows.ndim != 1:
            raise GenomeError(f"a Genome holds one genome of shape ({N_ROWS},), got {rows.shape!r}")
        rows = rows.copy()
        rows.setflags(write=False)
        object.__setattr__(self, "rows", rows)

    @classmethod
    def from_int(cls, value: int) -> "Genome":
        return cls(rows_from_int(value))

    @classmethod
    def from_hex(cls, text: str) -> "Genome":
        return cls(rows_from_hex(text))

    @classmethod
    def from_bits(cls, bits) -> "Genome":
        return cls(rows_from_bits(bits))

    def to_int(self) -> int:
        return int_from_rows(self.rows)

    def to_hex(self) -> str:
        return hex_from_rows(self.rows)

    def to_bits(self) -> np.ndarray:
        return bits_from_rows(self.rows)

    def __eq__(self, other):
        return isinstance(other, Genome) and np.array_equal(self.rows, other.rows)

    def __hash__(self):
        return hash(self.rows.tobytes())

    def __repr__(self):
        return f"Genome.from_hex({self.to_hex()!r})"

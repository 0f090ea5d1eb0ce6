"""Shared test vectors for the AND-OR array, its reference model and the EHW boards.

One list of genomes (rows form, SPEC section 3) that every check uses -- the Amaranth simulator,
cocotb on the generated Verilog and the NumPy reference -- so that the three agree on the same
cases: random genomes of varied density from a fixed seed, plus hand-made edge genomes.

Run ``python tests/vectors.py OUT.json`` (or call :func:`write_json`) to store them for a process
that cannot import numpy-side helpers; cocotb testbenches import this module directly.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from ga.genome import N_ROWS, ROW_BITS, hex_from_rows
from ga.motions import N_INPUTS, N_OUTPUTS

SEED = int(os.environ.get("EHW_VECTOR_SEED", "20261121"))
N_RANDOM = int(os.environ.get("EHW_VECTOR_COUNT", "56"))

_OUT_SHIFT = 2 * N_INPUTS


def _row(literals: dict[int, int] | None = None, outputs: int = 0) -> int:
    """A row word from {input i: +1 for x_i, -1 for NOT x_i, 0 for both} and a 3-bit output mask."""
    word = 0
    for i, polarity in (literals or {}).items():
        if polarity >= 0:
            word |= 1 << (2 * i)
        if polarity <= 0:
            word |= 1 << (2 * i + 1)
    return word | (outputs << _OUT_SHIFT)


def random_genomes(count: int = N_RANDOM, seed: int = SEED) -> np.ndarray:
    """``count`` genomes (count, 50) whose density sweeps from very specific to very broad rows.

    Genome g connects each input of each row with probability p_g (x_i or NOT x_i, equally
    likely), p_g going from 0.95 (rows of ~7.6 literals that fire in ~1 state) down to 0.05
    (rows that fire almost everywhere), so truth tables range from mostly 0 to saturated. One
    genome in eight also carries contradictory literal pairs (both x_i and NOT x_i), and one in
    eight is raw uniform random bits (about half the rows contradictory).
    """
    rng = np.random.default_rng(seed)
    genomes = np.zeros((count, N_ROWS), dtype=np.uint32)
    densities = np.linspace(0.95, 0.05, count)
    for g in range(count):
        if g % 8 == 7:
            genomes[g] = rng.integers(0, 1 << ROW_BITS, size=N_ROWS, dtype=np.uint32)
            continue
        connected = rng.random((N_ROWS, N_INPUTS)) < densities[g]
        negated = rng.random((N_ROWS, N_INPUTS)) < 0.5
        both = (rng.random((N_ROWS, N_INPUTS)) < 0.05) if g % 8 == 3 else np.zeros_like(connected)
        pos = connected & (~negated | both)
        neg = connected & (negated | both)
        shifts = np.arange(N_INPUTS, dtype=np.uint32)
        words = ((pos.astype(np.uint32) << (2 * shifts)) | (neg.astype(np.uint32) << (2 * shifts + 1))).sum(
            axis=1, dtype=np.uint32
        )
        outputs = rng.integers(0, 1 << N_OUTPUTS, size=N_ROWS, dtype=np.uint32)
        genomes[g] = words | (outputs << _OUT_SHIFT)
    return genomes


def edge_genomes() -> dict[str, np.ndarray]:
    """Named hand-made genomes that probe the corners of SPEC section 3."""
    all_out = (1 << N_OUTPUTS) - 1
    edges: dict[str, list[int]] = {}
    edges["all_zeros"] = [0] * N_ROWS  # empty rows fire but drive nothing: y = 0
    edges["all_ones"] = [(1 << ROW_BITS) - 1] * N_ROWS  # every row contradictory: y = 0
    edges["empty_row_fires"] = [_row(None, 0b101)] + [0] * (N_ROWS - 1)  # y = 5 everywhere
    edges["empty_last_row"] = [0] * (N_ROWS - 1) + [_row(None, 0b100)]  # arch bit 949 alone
    edges["single_literal"] = [0] * 10 + [_row({3: +1}, 0b010)] + [0] * (N_ROWS - 11)
    edges["single_not_literal"] = [0] * (N_ROWS - 1) + [_row({7: -1}, 0b001)]
    edges["single_literal_x0"] = [_row({0: +1}, 0b001)] + [0] * (N_ROWS - 1)  # arch bit 0
    edges["contradictory_rows"] = [_row({i % N_INPUTS: 0}, all_out) for i in range(N_ROWS)]
    edges["contradiction_beside_valid"] = [_row({2: 0, 5: +1}, all_out), _row({5: -1}, 0b010)] + [
        _row({1: 0}, all_out)
    ] * (N_ROWS - 2)
    # Each row a minterm (all 8 literals): 50 distinct states with their own motion, rest 0.
    minterms = []
    for r in range(N_ROWS):
        state = (r * 37 + 11) % 256
        minterms.append(_row({i: +1 if state >> i & 1 else -1 for i in range(N_INPUTS)}, (r % 7) + 1))
    edges["minterms"] = minterms
    # One output per row pattern, every literal of one polarity: checks the OR plane per bit.
    edges["all_positive_literals"] = [_row({i: +1 for i in range(N_INPUTS)}, all_out)] + [0] * (N_ROWS - 1)
    edges["all_negative_literals"] = [_row({i: -1 for i in range(N_INPUTS)}, all_out)] + [0] * (N_ROWS - 1)
    edges["per_input_rows"] = [
        _row({r % N_INPUTS: +1 if r < 25 else -1}, 1 << (r % N_OUTPUTS)) for r in range(N_ROWS)
    ]
    return {name: np.array(words, dtype=np.uint32) for name, words in edges.items()}


def all_genomes() -> list[tuple[str, np.ndarray]]:
    """Every shared vector as (name, rows (50,)): the edge genomes first, then the random ones."""
    cases = list(edge_genomes().items())
    cases += [(f"random_{g:02d}", rows) for g, rows in enumerate(random_genomes())]
    return cases


def population() -> tuple[list[str], np.ndarray]:
    """All shared vectors as names and one (P, 50) population."""
    cases = all_genomes()
    return [name for name, _ in cases], np.stack([rows for _, rows in cases])


def write_json(path: os.PathLike | str) -> Path:
    """Store the vectors as [{"name", "hex"}] (238-digit genome text) for other processes."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    data = [{"name": name, "hex": hex_from_rows(rows)} for name, rows in all_genomes()]
    path.write_text(json.dumps(data, indent=1) + "\n")
    return path


if __name__ == "__main__":
    import sys

    print(write_json(sys.argv[1] if len(sys.argv) > 1 else "build/vectors.json"))

"""Genetic operators for the 50-term DNF genome, grouped by role (init, selection, crossover, mutation).

Every operator works on populations in the rows form of `ga.genome` ((P, 50) uint32, one 19-bit
row word per term) and takes an explicit ``numpy.random.Generator``; none touches global state.

Vocabulary used below (SPEC section 3):

- a *literal field* is the 2-bit pair (bit 2i: x_i, bit 2i+1: NOT x_i) of input i in a row; its
  three legal values are ``DONT_CARE`` (00), ``POSITIVE`` (01, x_i) and ``NEGATIVE`` (10, NOT x_i).
  The fourth value (11, both connected) makes the row never fire; no operator here produces it.
- a row is *off* when it drives no output (its three output bits are 0): it can then never change
  a motion, whatever its literals. Switching a row off keeps its literals, so switching it back on
  restores a specific term. Off rows are the genome's spare capacity for new terms.

Why these operators (SPEC section 11, "OR-plane saturation"): broad rows fire in many states and
OR their outputs together, so random per-bit genomes drift towards motion 7 everywhere and one
mutation rarely changes one state's motion. The paper's rows fire in about 5 of the 256 states,
i.e. 5-6 connected literals. So initialisation and mutation work per literal with a strong bias to
*connected* literals (``literal_p``), rows carry one output pattern drawn uniformly, and a
state-targeted operator (`set_state_motion`) can rewrite the motion of one given state.
"""

from __future__ import annotations

import numpy as np

from ga.genome import LITERAL_MASK, N_ROWS, OUTPUT_MASK, OUTPUT_SHIFT, ROW_DTYPE, validate_rows
from ga.motions import N_INPUTS, N_MOTIONS, N_OUTPUTS, N_STATES

DONT_CARE, POSITIVE, NEGATIVE, CONTRADICTION = 0, 1, 2, 3

# Defaults, chosen on the measurements recorded in docs/offline.md.
DEFAULT_LITERAL_P = 0.72  # P(a literal is connected): mean 5.8 literals, ~6 states per row
DEFAULT_OFF_P = 0.5  # P(a fresh row is off): half the rows are spare capacity

_INPUTS = np.arange(N_INPUTS, dtype=ROW_DTYPE)


# ---------------------------------------------------------------------------------------------
# Helpers on literal fields
# ---------------------------------------------------------------------------------------------


def literal_fields(rows) -> np.ndarray:
    """The eight literal fields of every row: (..., 50, 8) uint8 with values 0..3."""
    rows = validate_rows(rows)
    return ((rows[..., None] >> (2 * _INPUTS)) & 3).astype(np.uint8)


def rows_from_fields(fields, outputs) -> np.ndarray:
    """Row words from literal fields (..., 8) and output codes (...) (the inverse of the split)."""
    fields = np.asarray(fields, dtype=ROW_DTYPE)
    literals = np.bitwise_or.reduce(fields << (2 * _INPUTS), axis=-1)
    return (literals | (np.asarray(outputs, dtype=ROW_DTYPE) << OUTPUT_SHIFT)).astype(ROW_DTYPE)


def row_outputs(rows) -> np.ndarray:
    """The 3-bit output code of every row (0 = the row is off)."""
    return (validate_rows(rows) >> OUTPUT_SHIFT) & ((1 << N_OUTPUTS) - 1)


def is_off(rows) -> np.ndarray:
    """True for rows that drive no output or can never fire (a contradictory literal)."""
    fields = literal_fields(rows)
    return (row_outputs(rows) == 0) | (fields == CONTRADICTION).any(axis=-1)


def row_fires(rows, state: int) -> np.ndarray:
    """True for each row (any leading shape) whose AND plane holds in world state ``state``."""
    if not 0 <= state < N_STATES:
        raise ValueError(f"a world state is in 0..{N_STATES - 1}, got {state!r}")
    rows = validate_rows(rows)
    # A literal fails when x_i is connected and the bit is 0, or NOT x_i is connected and it is 1.
    ones = sum(1 << (2 * i) for i in range(N_INPUTS) if not state >> i & 1)  # x_i with x_i = 0
    zeros = sum(1 << (2 * i + 1) for i in range(N_INPUTS) if state >> i & 1)  # NOT x_i with x_i = 1
    return (rows & ROW_DTYPE(ones | zeros)) == 0


def _draw_fields(rng: np.random.Generator, shape, literal_p: float) -> np.ndarray:
    """Literal fields drawn independently: connected with ``literal_p``, either polarity equally."""
    u = rng.random(shape)
    return np.where(u < literal_p / 2, POSITIVE, np.where(u < literal_p, NEGATIVE, DONT_CARE)).astype(
        np.uint8
    )


def _check_rate(name: str, value: float) -> None:
    if not 0.0 <= value <= 1.0:
        raise ValueError(f"{name} must be a probability in [0, 1], got {value!r}")


# ---------------------------------------------------------------------------------------------
# Initialisation
# ---------------------------------------------------------------------------------------------


def random_rows(
    rng: np.random.Generator, shape, literal_p: float = DEFAULT_LITERAL_P, off_p: float = DEFAULT_OFF_P
) -> np.ndarray:
    """Fresh specific rows of any shape.

    Each of the eight literals is independently don't-care (1 - ``literal_p``), x_i
    (``literal_p``/2) or NOT x_i (``literal_p``/2), never both; with ``literal_p`` = 0.72 a row
    connects 5.8 literals on average and fires in 256 (1 - literal_p/2)^8 = 6.1 states (the paper's
    "about 5"). With probability ``off_p`` the row is off (output 0), otherwise it drives one of
    the 7 non-empty output sets, uniformly.
    """
    _check_rate("literal_p", literal_p)
    _check_rate("off_p", off_p)
    shape = (int(shape),) if np.isscalar(shape) else tuple(int(d) for d in shape)
    fields = _draw_fields(rng, shape + (N_INPUTS,), literal_p)
    outputs = rng.integers(1, N_MOTIONS, size=shape)
    outputs = np.where(rng.random(shape) < off_p, 0, outputs)
    return rows_from_fields(fields, outputs)


def random_population(
    rng: np.random.Generator, size: int, literal_p: float = DEFAULT_LITERAL_P, off_p: float = DEFAULT_OFF_P
) -> np.ndarray:
    """A random population (size, 50) of specific rows (see `random_rows`)."""
    if size < 1:
        raise ValueError(f"a population has at least one individual, got size {size!r}")
    return random_rows(rng, (int(size), N_ROWS), literal_p, off_p)


# ---------------------------------------------------------------------------------------------
# Selection
# ---------------------------------------------------------------------------------------------


def tournament(rng: np.random.Generator, fitness, n: int, size: int) -> np.ndarray:
    """Indices of ``n`` tournament winners: each the fittest of ``size`` individuals drawn uniformly
    with replacement (ties go to the first drawn)."""
    fitness = np.asarray(fitness, dtype=float)
    if fitness.ndim != 1 or fitness.size == 0:
        raise ValueError(f"fitness must be a non-empty vector, got shape {fitness.shape!r}")
    if size < 1:
        raise ValueError(f"tournament size must be at least 1, got {size!r}")
    contestants = rng.integers(0, fitness.size, size=(int(n), int(size)))
    winner = np.argmax(fitness[contestants], axis=1)
    return contestants[np.arange(int(n)), winner]


def elite(fitness, count: int) -> np.ndarray:
    """Indices of the ``count`` fittest individuals, best first (stable: ties keep index order)."""
    fitness = np.asarray(fitness, dtype=float)
    return np.argsort(-fitness, kind="stable")[: int(count)]


# ---------------------------------------------------------------------------------------------
# Crossover (row-aligned: a row is a term of the DNF and is never cut)
# ---------------------------------------------------------------------------------------------


def uniform_row_crossover(rng: np.random.Generator, a, b) -> np.ndarray:
    """One child per pair: each of the 50 rows from parent ``a`` or ``b`` with probability 1/2.

    Rows are ORed together, so their order carries no meaning; taking whole rows keeps every term
    of the child a term of one parent.
    """
    a, b = validate_rows(a), validate_rows(b)
    take_b = rng.random(a.shape) < 0.5
    return np.where(take_b, b, a).astype(ROW_DTYPE)


def two_point_row_crossover(rng: np.random.Generator, a, b) -> np.ndarray:
    """One child per pair: rows [i, j) from ``b``, the rest from ``a`` (i < j drawn per pair)."""
    a, b = validate_rows(a), validate_rows(b)
    pairs = a.shape[:-1]
    cuts = np.sort(rng.integers(0, N_ROWS + 1, size=pairs + (2,)), axis=-1)
    idx = np.arange(N_ROWS)
    take_b = (idx >= cuts[..., :1]) & (idx < cuts[..., 1:])
    return np.where(take_b, b, a).astype(ROW_DTYPE)


CROSSOVERS = {"uniform": uniform_row_crossover, "two_point": two_point_row_crossover}


# ---------------------------------------------------------------------------------------------
# Mutation (vectorised over a population; each returns a new array)
# ---------------------------------------------------------------------------------------------


def _sparse_sites(rng: np.random.Generator, total: int, rate: float) -> np.ndarray:
    """Distinct sites in range(total), each chosen with probability about ``rate``.

    For small rates, a binomial count then uniform draws, deduplicated: the same law as one
    Bernoulli per site up to O(rate) relative collisions, without drawing ``total`` random numbers (this keeps a 500-genome
    generation well under a millisecond).
    """
    _check_rate("mutation rate", rate)
    if rate > 0.05:  # collisions would matter: draw one Bernoulli per site
        return np.flatnonzero(rng.random(total) < rate)
    count = rng.binomial(total, rate) if total else 0
    if count == 0:
        return np.zeros(0, dtype=np.int64)
    return np.unique(rng.integers(0, total, size=count))


def mutate_literals(
    rng: np.random.Generator, pop, rate: float, literal_p: float = DEFAULT_LITERAL_P
) -> np.ndarray:
    """Move each literal field, with probability ``rate``, to one of its two other legal values.

    From don't-care it becomes x_i or NOT x_i (1/2 each); from x_i it becomes NOT x_i or
    don't-care, in the ratio literal_p/2 : (1 - literal_p) of the initial law, so mutation keeps
    rows about as specific as `random_rows` makes them. A contradictory field (never produced
    here) is reset to a legal one.
    """
    pop = validate_rows(pop).copy()
    flat = pop.reshape(-1)
    sites = _sparse_sites(rng, flat.size * N_INPUTS, rate)
    if sites.size == 0:
        return pop
    row, inp = np.divmod(sites, N_INPUTS)
    shift = (2 * inp).astype(ROW_DTYPE)
    old = (flat[row] >> shift) & 3
    u = rng.random(sites.size)
    p_to_dc = (1 - literal_p) / (1 - literal_p / 2)  # from a connected literal to don't-care
    flip = np.where(old == POSITIVE, NEGATIVE, POSITIVE)
    new = np.where(
        old == DONT_CARE,
        np.where(u < 0.5, POSITIVE, NEGATIVE),
        np.where(old == CONTRADICTION, DONT_CARE, np.where(u < p_to_dc, DONT_CARE, flip)),
    ).astype(ROW_DTYPE)
    # Distinct sites in one row touch disjoint bits, so accumulating their XOR deltas is exact.
    delta = np.zeros(flat.size, dtype=ROW_DTYPE)
    np.bitwise_or.at(delta, row, (old.astype(ROW_DTYPE) ^ new) << shift)
    flat ^= delta
    return pop


def mutate_outputs(rng: np.random.Generator, pop, rate: float) -> np.ndarray:
    """Flip each output bit (3 per row) with probability ``rate``; a row left with no output is off."""
    pop = validate_rows(pop).copy()
    flat = pop.reshape(-1)
    sites = _sparse_sites(rng, flat.size * N_OUTPUTS, rate)
    if sites.size:
        row, bit = np.divmod(sites, N_OUTPUTS)
        np.bitwise_xor.at(flat, row, (ROW_DTYPE(1) << (OUTPUT_SHIFT + bit).astype(ROW_DTYPE)))
    return pop


def switch_rows(rng: np.random.Generator, pop, rate: float) -> np.ndarray:
    """Switch each row, with probability ``rate``, off (clear its outputs, keep its literals) or,
    if it is off, on (a uniformly drawn non-empty output set)."""
    pop = validate_rows(pop).copy()
    flat = pop.reshape(-1)
    sites = _sparse_sites(rng, flat.size, rate)
    if sites.size:
        outputs = rng.integers(1, N_MOTIONS, size=sites.size).astype(ROW_DTYPE)
        words = flat[sites]
        on = (words & OUTPUT_MASK) != 0
        flat[sites] = np.where(on, words & LITERAL_MASK, (words & LITERAL_MASK) | (outputs << OUTPUT_SHIFT))
    return pop


def replace_rows(
    rng: np.random.Generator,
    pop,
    rate: float,
    literal_p: float = DEFAULT_LITERAL_P,
    off_p: float = 0.0,
) -> np.ndarray:
    """Replace each row, with probability ``rate``, by a fresh `random_rows` term (on by default)."""
    pop = validate_rows(pop).copy()
    flat = pop.reshape(-1)
    sites = _sparse_sites(rng, flat.size, rate)
    if sites.size:
        flat[sites] = random_rows(rng, (sites.size,), literal_p, off_p)
    return pop


def mutate(
    rng: np.random.Generator,
    pop,
    literal_rate: float,
    output_rate: float,
    switch_rate: float,
    replace_rate: float = 0.0,
    literal_p: float = DEFAULT_LITERAL_P,
) -> np.ndarray:
    """All the per-site mutations in a fixed order: literals, outputs, switch, replace."""
    pop = mutate_literals(rng, pop, literal_rate, literal_p)
    pop = mutate_outputs(rng, pop, output_rate)
    pop = switch_rows(rng, pop, switch_rate)
    if replace_rate:
        pop = replace_rows(rng, pop, replace_rate, literal_p)
    return pop


# ---------------------------------------------------------------------------------------------
# State-targeted mutation (SPEC section 11: change the motion of the state that just failed)
# ---------------------------------------------------------------------------------------------


def motion_in_state(rows, state: int) -> int:
    """The array's own motion in ``state`` (no reflex): OR of the outputs of the rows that fire."""
    rows = validate_rows(rows)
    fires = row_fires(rows, state)
    return int(np.bitwise_or.reduce(np.where(fires, row_outputs(rows), 0), axis=-1))


def set_state_motion(
    rng: np.random.Generator, genome, state: int, motion: int, n_literals: int = 6
) -> np.ndarray:
    """A copy of one genome whose array outputs ``motion`` in ``state`` (reflex not considered).

    1. Every on row that fires in ``state`` and drives a bit outside ``motion`` is narrowed: one
       of its don't-care inputs (drawn uniformly) is connected with the polarity that ``state``
       violates, so the row keeps half its other states and loses ``state``; a row with no
       don't-care left is switched off.
    2. If the remaining firing rows do not OR to ``motion`` exactly, a term matching ``state`` on
       ``n_literals`` inputs (drawn uniformly; the literals agree with ``state``) driving
       ``motion`` is written over an off row (drawn uniformly), or over a random row if none is
       off. For ``motion`` 0 step 1 already suffices.

    Other states change only where the narrowed or overwritten rows fired, so the edit is local.
    """
    if not 0 <= motion < N_MOTIONS:
        raise ValueError(f"a motion is in 0..{N_MOTIONS - 1}, got {motion!r}")
    if not 1 <= n_literals <= N_INPUTS:
        raise ValueError(f"n_literals must be in 1..{N_INPUTS}, got {n_literals!r}")
    rows = validate_rows(genome)
    if rows.ndim != 1:
        raise ValueError(f"set_state_motion takes one genome of shape ({N_ROWS},), got {rows.shape!r}")
    rows = rows.copy()
    fires = row_fires(rows, state)
    outputs = row_outputs(rows)
    fields = literal_fields(rows)
    for r in np.flatnonzero(fires & ((outputs & (7 ^ motion)) != 0)):
        free = np.flatnonzero(fields[r] == DONT_CARE)
        if free.size == 0:
            rows[r] &= ROW_DTYPE(LITERAL_MASK)
            continue
        i = int(rng.choice(free))
        violated = NEGATIVE if state >> i & 1 else POSITIVE  # the literal that is false in state
        rows[r] |= ROW_DTYPE(violated << (2 * i))
    if motion_in_state(rows, state) != motion:
        inputs = rng.choice(N_INPUTS, size=n_literals, replace=False)
        new_fields = np.zeros(N_INPUTS, dtype=np.uint8)
        new_fields[inputs] = np.where((state >> inputs) & 1, POSITIVE, NEGATIVE)
        off = np.flatnonzero(is_off(rows))
        r = int(rng.choice(off)) if off.size else int(rng.integers(N_ROWS))
        rows[r] = rows_from_fields(new_fields, motion)
    return rows


def avoid_state_motion(rng: np.random.Generator, genome, state: int, n_literals: int = 6) -> np.ndarray:
    """A copy of one genome whose array outputs, in ``state``, a motion other than its current one
    (drawn uniformly among the 7 others), via `set_state_motion`."""
    current = motion_in_state(genome, state)
    others = [m for m in range(N_MOTIONS) if m != current]
    return set_state_motion(rng, genome, state, int(rng.choice(others)), n_literals)

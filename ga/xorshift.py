"""The random source of the learning engine (SPEC section 12): the reference of ``hdl.learner_lane``'s
generators, used by ``ga.hardware_ga``.

Seven xorshift32 generators per lane (Marsaglia's 13/17/5 triple: a register and three
shift-XORs, one step per cycle): ``SEL`` draws the tournament contestants and the crossover
decision, ``ROW0`` .. ``ROW5`` one word each per bred row. Every generator steps on a fixed schedule, whatever
the draws decide: per child slot, ``SEL`` steps 2T + 1 times and each row generator 50 times, in
every lane and every slot (a slot with no child, past the end of the population, still steps).
So the k-th draw of a generator is its k-th state after the seed, and the reference computes a
whole pass of draws at once (`xorshift_stream`, by doubling on the linear map of one step).
Generator ``g`` of lane ``j`` starts from ``seed ^ seed_salt(j, g)`` (``SEED_FALLBACK`` if that is 0).
A rate is a threshold on a 16-bit field of one word: the event happens when the field is below it.

The bits of each draw that the GA uses are ``ga.hardware_ga``'s field constants.
"""

from __future__ import annotations

import numpy as np

MASK32 = 0xFFFF_FFFF
SEL, ROW0, ROW1, ROW2, ROW3, ROW4, ROW5 = range(7)  # the generators of one lane
GENERATORS = 7
ROW_GENERATORS = (ROW0, ROW1, ROW2, ROW3, ROW4, ROW5)
SEED_FALLBACK = 0x9E37_79B9  # a generator's state must not be 0
_SALT_STEP = 0x6C07_8965  # odd: the salts of distinct (lane, generator) are distinct


def seed_salt(lane: int, generator: int) -> int:
    """The constant XORed into the seed for generator ``generator`` of lane ``lane``."""
    return ((GENERATORS * lane + generator + 1) * _SALT_STEP) & MASK32


def lane_seeds(seed: int, lanes: int) -> np.ndarray:
    """Initial states (lanes, GENERATORS) uint32 of every generator, from a 32-bit ``seed``."""
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not 0 <= seed <= MASK32:
        raise ValueError(f"a hardware GA seed is a 32-bit unsigned integer, got {seed!r}")
    states = np.empty((lanes, GENERATORS), dtype=np.uint32)
    for j in range(lanes):
        for g in range(GENERATORS):
            v = int(seed) ^ seed_salt(j, g)
            states[j, g] = v if v else SEED_FALLBACK
    return states


def xorshift32(x: int) -> int:
    """One step of the generator (the draw is the new state)."""
    x ^= (x << 13) & MASK32
    x ^= x >> 17
    x ^= (x << 5) & MASK32
    return x


def _step_words(x: np.ndarray) -> np.ndarray:
    x = x.astype(np.uint32, copy=True)
    x ^= x << np.uint32(13)
    x ^= x >> np.uint32(17)
    x ^= x << np.uint32(5)
    return x


def _tables_of(columns: np.ndarray) -> np.ndarray:
    """(4, 256) uint32 byte tables of the GF(2)-linear map with these 32 column images."""
    tables = np.zeros((4, 256), dtype=np.uint32)
    for byte in range(4):
        for bit in range(8):
            has = (np.arange(256) >> bit) & 1 == 1
            tables[byte, has] ^= columns[8 * byte + bit]
    return tables


def _apply(tables: np.ndarray, x: np.ndarray) -> np.ndarray:
    return (tables[0][x & 0xFF] ^ tables[1][(x >> 8) & 0xFF]
            ^ tables[2][(x >> 16) & 0xFF] ^ tables[3][x >> 24])


def _power_tables(count: int = 24) -> list[np.ndarray]:
    """Byte tables of the step map raised to 1, 2, 4, ... 2^(count-1)."""
    columns = _step_words(np.uint32(1) << np.arange(32, dtype=np.uint32))
    out = []
    for _ in range(count):
        tables = _tables_of(columns)
        out.append(tables)
        columns = _apply(tables, columns)  # square the map
    return out


_POWERS = _power_tables()
_BLOCK_LOG2 = 4  # xorshift_stream: the recurrence runs 16 steps from every 16th state


def xorshift_stream(states, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The next ``n`` draws of every generator in ``states`` (any shape, uint32): an array of
    shape states.shape + (n,), and the states after them. No Python loop over the draws: the
    states after 0, 16, 32, ... steps come from doubling on the linear step map (the block of
    jumps k..2k-1 is the map to the power 16 k applied to jumps 0..k-1), then 16 steps of the
    recurrence run from all of them at once."""
    states = np.asarray(states, dtype=np.uint32)
    if n <= 0:
        return np.zeros(states.shape + (0,), dtype=np.uint32), states.copy()
    if n > 1 << len(_POWERS):
        raise ValueError(f"at most {1 << len(_POWERS)} draws at once, asked {n!r}")
    block = 1 << _BLOCK_LOG2
    m = -(-n // block)
    starts = np.empty(states.shape + (m,), dtype=np.uint32)
    starts[..., 0] = states
    filled, k = 1, _BLOCK_LOG2
    while filled < m:
        take = min(filled, m - filled)
        starts[..., filled:filled + take] = _apply(_POWERS[k], starts[..., :take])
        filled += take
        k += 1
    out = np.empty(states.shape + (m, block), dtype=np.uint32)
    x = starts
    for i in range(block):
        x = _step_words(x)
        out[..., i] = x
    out = out.reshape(states.shape + (m * block,))[..., :n]
    return out, out[..., -1].copy()

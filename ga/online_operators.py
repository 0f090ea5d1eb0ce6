"""On-line-specific GA pieces: state-targeted mutants and the measurements of the instrumentation.

The general operators (per-literal mutation, off rows, row crossover, ``set_state_motion``) live in
``ga.operators`` and the ask/tell GA in ``ga.evolution``; this module adds what only the on-line
loop needs (SPEC section 11):

- :func:`targeted_mutants`: copies of a genome whose motion in the state that just failed is
  rewritten to a motion the world model does not know to crash there;
- :func:`motion_change_rate`: how often one mutation changes one state's motion;
- :func:`diversity`: distinct behaviours and motion entropy of a population on the model's states.

Every function takes an explicit ``numpy.random.Generator``.
"""

from __future__ import annotations

import numpy as np

from ga.genome import ROW_DTYPE, validate_rows
from ga.motions import N_MOTIONS
from ga.operators import set_state_motion
from ga.truth_table import truth_tables


def targeted_mutants(
    rng: np.random.Generator, genome, state: int, avoid, count: int, n_literals: int = 6
) -> np.ndarray:
    """``count`` copies of ``genome`` whose array outputs, in ``state``, a motion not in ``avoid``.

    The new motions are drawn uniformly (with replacement) from the motions outside ``avoid``
    (typically: the motion that just failed and the motions the model records as crashes in
    ``state``). Returns (count, 50) rows; an empty array when every motion is to be avoided.
    """
    choices = [m for m in range(N_MOTIONS) if m not in set(int(a) for a in avoid)]
    if count <= 0 or not choices:
        return np.zeros((0, validate_rows(genome).shape[-1]), dtype=ROW_DTYPE)
    motions = rng.choice(choices, size=count)
    return np.stack([set_state_motion(rng, genome, state, int(m), n_literals) for m in motions.tolist()])


def motion_change_rate(rows, state: int, rng: np.random.Generator, mutate, trials: int = 200) -> float:
    """How often one application of ``mutate(rng, rows (n, 50)) -> rows`` changes ``state``'s motion
    (reflex on), over ``trials`` copies of one genome or over the rows of a population."""
    rows = validate_rows(rows)
    base = np.repeat(rows[None], trials, axis=0) if rows.ndim == 1 else rows
    before = truth_tables(base, reflex=True)[:, state]
    after = truth_tables(mutate(rng, base), reflex=True)[:, state]
    return float(np.mean(before != after))


def diversity(population, states) -> dict:
    """Population diversity on the model's states ``states``: the number of distinct behaviours
    (truth tables restricted to the states) and the mean per-state entropy of the motion (bits)."""
    states = np.asarray(states, dtype=np.int64)
    if states.size == 0:
        return {"distinct_behaviours": 0, "mean_entropy_bits": 0.0}
    tables = truth_tables(validate_rows(population), reflex=True)[:, states]  # (P, |S|)
    distinct = int(np.unique(tables, axis=0).shape[0])
    counts = np.stack([(tables == m).sum(axis=0) for m in range(N_MOTIONS)])  # (8, |S|)
    prob = counts / tables.shape[0]
    with np.errstate(divide="ignore", invalid="ignore"):
        entropy = -np.where(prob > 0, prob * np.log2(prob), 0.0).sum(axis=0)
    return {"distinct_behaviours": distinct, "mean_entropy_bits": round(float(entropy.mean()), 4)}

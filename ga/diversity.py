"""Diversity of a population on the world model's states (the on-line phase records, SPEC
section 11): distinct behaviours and the mean entropy of the motion per state."""

from __future__ import annotations

import numpy as np

from ga.genome import validate_rows
from ga.motions import N_MOTIONS
from ga.truth_table import truth_tables


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

"""The reactive baseline proves the default arena fair (SPEC section 11: arena traps)."""

from __future__ import annotations

import numpy as np

from ga.motions import REFLEX_TABLE
from sim_world.baseline import baseline_table, rules_table, run_baseline
from sim_world.course import DEFAULT_MAX_LEG_STEPS
from sim_world.world import DEFAULT_NOISE


def test_table_keeps_the_reflex():
    for table in (baseline_table(), rules_table()):
        assert table.shape == (256,) and table.dtype == np.uint8 and table.max() < 8
        reflex = REFLEX_TABLE >= 0
        assert np.array_equal(table[reflex], REFLEX_TABLE[reflex])


def test_baseline_reaches_64_targets_noise_free():
    res = run_baseline("default")
    assert res.targets_reached == 64 and not res.crashed and not res.timed_out
    assert max(res.leg_steps) < DEFAULT_MAX_LEG_STEPS / 2


def test_baseline_reaches_64_targets_at_default_noise():
    res = run_baseline("default", DEFAULT_NOISE, seed=0)
    assert res.targets_reached == 64 and not res.crashed and not res.timed_out


def test_baseline_in_the_simpler_arenas():
    for arena in ("one_obstacle", "empty"):
        res = run_baseline(arena)
        assert res.targets_reached == 64 and not res.crashed and not res.timed_out, arena

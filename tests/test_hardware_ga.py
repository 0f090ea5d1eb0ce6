"""The hardware GA's NumPy reference (ga.hardware_ga) against plain per-cycle Python, and the
integer score against the SPEC's fitness."""

from fractions import Fraction

import numpy as np
import pytest

from ga import hardware_ga as hg
from ga.evaluator import EvalResult, fitness
from ga.genome import N_ROWS
from ga.operators import random_population
from ga.world_model import WorldModel


def _model(seed: int, steps: int = 400) -> WorldModel:
    """A world model from a random walk (obstacle states, crashes, loops)."""
    rng = np.random.default_rng(seed)
    model = WorldModel()
    s = int(rng.integers(256))
    model.visit(s)
    for _ in range(steps):
        a = int(rng.integers(8))
        crashed = bool(rng.random() < 0.1)
        s2 = s if crashed else int(rng.choice([s, int(rng.integers(256)), (s + 1) % 256]))
        model.observe(s, a, s2, crashed)
        s = s2 if rng.random() < 0.9 else int(rng.integers(256))
        model.visit(s)
    return model


def test_xorshift_stream_equals_the_scalar_steps():
    states = np.array([[1, 0xDEADBEEF], [hg.SEED_FALLBACK, 12345]], dtype=np.uint32)
    out, after = hg.xorshift_stream(states, 1000)
    for idx in np.ndindex(states.shape):
        x = int(states[idx])
        for k in range(1000):
            x = hg.xorshift32(x)
            assert int(out[idx][k]) == x
        assert int(after[idx]) == x


def test_lane_seeds_are_distinct_and_never_zero():
    seeds = hg.lane_seeds(hg.seed_salt(0, 0), 16)  # seed ^ salt = 0 for generator 0 of lane 0
    assert seeds[0, 0] == hg.SEED_FALLBACK
    assert len(np.unique(seeds)) == seeds.size
    with pytest.raises(ValueError, match="32-bit"):
        hg.lane_seeds(1 << 32, 2)


def test_score_orders_exactly_as_the_rational_fitness():
    rng = np.random.default_rng(3)
    n = 170
    c, l = rng.integers(0, 20, 4000), rng.integers(0, 25, 4000)
    d = rng.integers(0, 60, 4000) * 50
    s = hg.score(c, l, d, n)
    exact = [Fraction(1, 2) * (1 - Fraction(int(ci), n)) + Fraction(2, 5) * (1 - Fraction(int(li), n))
             + Fraction(1, 10) * Fraction(int(di), n * 50) for ci, li, di in zip(c, l, d)]
    assert all(si == e * 10 * 50 * n for si, e in zip(s.tolist(), exact))  # score = 10 D N fitness
    f = fitness(EvalResult(c, l, d), n)
    order = np.argsort(-s, kind="stable")
    # the float fitness is non-increasing along the score order, and strictly where scores differ
    gaps = np.diff(f[order])
    strict = np.diff(s[order]) < 0
    assert (gaps[strict] < 0).all()
    assert np.abs(gaps[~strict]).max() < 1e-12  # ties: at most rounding noise apart
    assert (~strict).sum() > 0  # the sample holds ties (so the tie rule is exercised)


def _breed_python(ga: hg.HardwareGA) -> np.ndarray:
    """One pass of breeding, cycle by cycle as the hardware does it (scalar generators)."""
    cfg = ga.config
    P, T, L = cfg.population, cfg.tournament, cfg.lanes
    gens = [[int(x) for x in lane] for lane in ga.generators]
    children = np.zeros((P, N_ROWS), dtype=np.uint32)
    for s in range(cfg.slots):
        for j in range(L):
            i = s * L + j
            draws = []
            for _ in range(2 * T + 1):
                gens[j][hg.SEL] = hg.xorshift32(gens[j][hg.SEL])
                draws.append(gens[j][hg.SEL])
            row_words = []
            for _ in range(N_ROWS):
                for g in hg.ROW_GENERATORS:
                    gens[j][g] = hg.xorshift32(gens[j][g])
                row_words.append([gens[j][g] for g in hg.ROW_GENERATORS])
            if i >= P:
                continue
            if ga.scores is None:
                children[i] = ga.population[i]
                continue
            if i == 0:
                best = max(range(P), key=lambda k: (ga.scores[k], -k))
                children[i] = ga.population[best]
                continue
            winners = []
            for t0 in (0, T):
                win = None
                for w in draws[t0:t0 + T]:
                    k = ((w >> 16) * P) >> 16
                    if win is None or ga.scores[k] > ga.scores[win]:
                        win = k
                winners.append(win)
            cross = (draws[2 * T] >> 16) < cfg.cross_threshold
            for r, (r0, r1, r2, r3, r4, r5) in enumerate(row_words):
                parent = winners[1] if cross and r0 & 1 else winners[0]
                word = int(ga.population[parent, r])
                if (r0 >> 16) < cfg.literal_threshold:
                    sh = 2 * ((r0 >> 1) & 7)
                    old = (word >> sh) & 3
                    if old == 0:
                        new = 2 if (r0 >> 4) & 1 else 1
                    elif old == 3 or ((r0 >> 8) & 0xFF) < cfg.to_dc_threshold:
                        new = 0
                    else:
                        new = 3 - old
                    word = (word & ~(3 << sh)) | (new << sh)
                if (r1 >> 16) < cfg.output_threshold:
                    word ^= 1 << (16 + (((r1 & 0xFF) * 3) >> 8))
                if (r2 >> 16) < cfg.switch_threshold:
                    literals = word & 0xFFFF
                    word = literals if word >> 16 else literals | (((((r2 & 0xFF) * 7) >> 8) + 1) << 16)
                if (r3 >> 16) < cfg.replace_threshold:
                    word = ((((r3 & 0xFF) * 7) >> 8) + 1) << 16
                    for f in range(8):
                        byte = ((r4 if f < 4 else r5) >> (8 * (f % 4))) & 0xFF
                        if byte < cfg.connect_threshold:
                            word |= (1 + ((r3 >> (8 + f)) & 1)) << (2 * f)
                children[i, r] = word
    return children


@pytest.mark.parametrize("lanes,population,tournament", [(1, 7, 3), (3, 20, 5), (8, 30, 20)])
def test_vectorised_passes_equal_the_per_cycle_model(lanes, population, tournament):
    # high rates so that every operator fires often
    cfg = hg.HardwareGAConfig(population=population, tournament=tournament, lanes=lanes,
                              literal_rate=0.05, output_rate=0.1, switch_rate=0.2, replace_rate=0.1)
    model = _model(1)
    pop = random_population(np.random.default_rng(2), population)
    ga = hg.HardwareGA(cfg, seed=77, population=pop)
    for _ in range(4):
        expected = _breed_python(ga)
        ga.run_pass(model)
        assert np.array_equal(ga.population, expected)


def test_elitism_and_improvement():
    model = _model(4)
    pop = random_population(np.random.default_rng(5), 60)
    ga = hg.HardwareGA(hg.HardwareGAConfig(population=60, tournament=5, lanes=4), 9, pop)
    ga.run_pass(model)
    first = int(ga.scores.max())
    bests = []
    for _ in range(8):
        prev_best = ga.best()
        ga.run_pass(model)
        assert np.array_equal(ga.population[0], prev_best)  # child 0 is the elite
        bests.append(int(ga.scores.max()))
    assert bests == sorted(bests) and bests[-1] > first


def test_learn_function_and_cycles():
    model = _model(6)
    pop = random_population(np.random.default_rng(7), 24)
    cfg = hg.HardwareGAConfig(population=24, tournament=4, lanes=3)
    best, last, counts = hg.learn(model, pop, 3, seed=5, config=cfg)
    ga = hg.HardwareGA(cfg, 5, pop)
    best2, counts2, cycles = ga.learn(model, 3)
    assert np.array_equal(best, best2) and counts == counts2 and np.array_equal(last, ga.population)
    assert cycles == 1 + 3 * hg.pass_cycles(model.n_states, cfg)
    with pytest.raises(ValueError, match="generations"):
        ga.learn(model, 0)


def test_config_checks():
    with pytest.raises(ValueError, match="lanes"):
        hg.HardwareGAConfig(lanes=0)
    with pytest.raises(ValueError, match="literal_rate"):
        hg.HardwareGAConfig(literal_rate=1.5)
    cfg = hg.HardwareGAConfig()
    assert cfg.literal_threshold == round(0.032 * 65536) and cfg.to_dc_threshold == 112
    assert cfg.replace_threshold == 328 and cfg.connect_threshold == 184


def test_escape_download_is_the_fittest_child_with_another_motion():
    from ga.motions import OBSTACLE_MASK
    from ga.operators import motion_in_state

    model = _model(8)
    pop = random_population(np.random.default_rng(9), 40)
    ga = hg.HardwareGA(hg.HardwareGAConfig(population=40, tournament=4, lanes=5), 3, pop)
    ga.learn(model, 2)
    state = next(int(s) for s in model.states if s & OBSTACLE_MASK)
    motion = motion_in_state(ga.best(), state)
    rows, counts, _ = ga.learn(model, 1, avoid=(state, motion))
    motions = np.array([motion_in_state(g, state) for g in ga.population])
    eligible = np.flatnonzero(motions != motion)
    assert ga.download_index == eligible[np.argmax(ga.scores[eligible])]
    assert motion_in_state(rows, state) != motion and counts == ga.counts.row(ga.download_index)
    with pytest.raises(ValueError, match="obstacle"):
        ga.learn(model, 1, avoid=(0, 0))

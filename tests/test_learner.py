"""The learning engine (hdl.learner) against its reference (ga.hardware_ga): populations, best,
counts, fail counts, scores and cycles, with failure-rate codes written between phases, in
Amaranth's simulator and (one short case) the generated Verilog in cocotb."""

import json
from pathlib import Path

import numpy as np
import pytest

from ga import hardware_ga as hg
from ga.fail_rates import prior_codes
from ga.motions import OBSTACLE_MASK
from ga.operators import motion_in_state, random_population
from ga.world_model import WorldModel

TB_DIR = Path(__file__).resolve().parent / "cocotb_tb"


def observations(seed: int, count: int, spread: int = 256):
    """A random walk of (state, motion, next_state, crashed) over ``spread`` states."""
    rng = np.random.default_rng(seed)
    out, s = [], int(rng.integers(spread))
    for _ in range(count):
        a = int(rng.integers(8))
        crashed = bool(rng.random() < 0.15)
        s2 = s if crashed else int(rng.integers(spread) if rng.random() < 0.4 else s ^ 1)
        out.append((s, a, s2, crashed))
        s = s2
    return out


def rate_writes(seed: int, obs, count: int, low: int = 0, high: int = 255):
    """``count`` failure-rate writes (state, motion, code) on pairs of the states of ``obs``,
    codes in low..high (the 8-bit port takes codes beyond RATE_ONE too)."""
    rng = np.random.default_rng(seed)
    states = sorted({o[0] for o in obs})
    return [(int(rng.choice(states)), int(rng.integers(8)), int(rng.integers(low, high + 1))) for _ in range(count)]


def reference_phases(config, seed, population, phases):
    ga = hg.HardwareGA(config, seed, population)
    model, codes = WorldModel(), prior_codes()
    out = []
    for obs, generations, avoid, rates in phases:
        for o in obs:
            model.observe(*o)
        for state, motion, code in rates:
            codes[state, motion] = code
        best, counts, cycles = ga.learn(model, generations, avoid=avoid, rates=codes)
        i = ga.download_index
        out.append({"best_index": i, "escaped": i != ga.best_index, "counts": counts,
                    "fails": int(ga.counts.fails[i]), "score": int(ga.scores[i]), "scores": ga.scores.copy(),
                    "cycles": cycles, "population": ga.population.copy(), "n_states": model.n_states})
    return out


def _crash_phase(obs, seed: int, low: int):
    """``obs``, then a crash on every motion of every state they visited, with a code in
    low..255 for every pair: every controller crashes everywhere (c = N), so its score is
    4 D N - F, and F, about 4 D a state, is on both sides of it (the signed comparisons)."""
    crashes = [(s, a, s, True) for s in sorted({o[0] for o in obs} | {o[2] for o in obs}) for a in range(8)]
    codes = np.random.default_rng(seed).integers(low, 256, len(crashes))
    return obs + crashes, (len(obs) + len(crashes), 2, [(s, a, int(c)) for (s, a, _, _), c in zip(crashes, codes)])


# Two regimes of the slot length C = max(N + 2, 2T + 54): breeding-bound (small model) and
# evaluation-bound (T = 1, a model of more than 53 states); high mutation rates so that every
# operator acts; a second phase after more observations continues from the first. Rate codes are
# written before each phase; in the first case's third phase every scored child crashes
# everywhere and the scores are of both signs.
_WALK, _CRASH_CUT = _crash_phase(observations(1, 40, 64), 7, 150)
CASES = [
    (hg.HardwareGAConfig(population=7, tournament=2, lanes=3, literal_rate=0.05, output_rate=0.1,
                         switch_rate=0.2, replace_rate=0.1), 123, _WALK,
     [(25, 2, rate_writes(1, _WALK[:25], 40)), (40, 1, rate_writes(2, _WALK[:40], 30)), _CRASH_CUT]),
    (hg.HardwareGAConfig(population=5, tournament=1, lanes=2, literal_rate=0.05, output_rate=0.1,
                         switch_rate=0.2, replace_rate=0.1), 7, observations(2, 200, 256),
     [(200, 2, rate_writes(3, observations(2, 200, 256), 60, high=250))]),
]


def _phases(obs, cuts):
    """(observations, generations, avoid, rate writes) of each phase."""
    out, last = [], 0
    for end, generations, rates in cuts:
        out.append((obs[last:end], generations, None, rates))
        last = end
    return out


def _with_escape(config, seed, population, phases):
    """The phases with an escape in the last one: avoid, in the first obstacle state of the
    model, the motion there of the best the reference would download without it."""
    plain = reference_phases(config, seed, population, phases)
    model = WorldModel()
    for obs, *_ in phases:
        for o in obs:
            model.observe(*o)
    state = next(int(s) for s in model.states if s & OBSTACLE_MASK)
    motion = motion_in_state(plain[-1]["population"][plain[-1]["best_index"]], state)
    obs, generations, _, rates = phases[-1]
    return phases[:-1] + [(obs, generations, (state, motion), rates)]


@pytest.mark.parametrize("case", range(len(CASES)))
def test_amaranth_learner_equals_reference(case):
    from hdl.learner_sim import simulate_learning

    config, seed, obs, cuts = CASES[case]
    population = random_population(np.random.default_rng(case), config.population)
    phases = _with_escape(config, seed, population, _phases(obs, cuts))
    got = simulate_learning(config, seed, population, phases)
    want = reference_phases(config, seed, population, phases)
    assert want[-1]["escaped"]  # the escape download is not the best
    if case == 1:
        assert want[0]["n_states"] + 2 > 2 * config.tournament + 1 + 50 + hg.ROW_LATENCY  # evaluation-bound
    assert all(w["fails"] > 0 for w in want)
    if case == 0:
        assert want[-1]["counts"][0] == want[-1]["n_states"] and want[-1]["scores"].min() < 0 < want[-1]["scores"].max()
    for g, w in zip(got, want):
        assert g["best_index"] == w["best_index"]
        assert g["counts"] == w["counts"] and g["fails"] == w["fails"] and g["score"] == w["score"]
        assert np.array_equal(np.array(g["population"], dtype=np.uint32), w["population"])
        # the cycle formula: cycles register = passes * pass_cycles, edges = learn_cycles
        assert g["edges"] == w["cycles"]
        assert g["cycles"] == w["cycles"] - 1


def test_learner_constructor_checks():
    from hdl.learner import Learner

    with pytest.raises(TypeError, match="HardwareGAConfig"):
        Learner({"population": 10})


@pytest.mark.cocotb
def test_cocotb_learner_verilog_equals_reference(tmp_path):
    """The generated Verilog of a small learner in cocotb (Icarus by default, EHW_SIM to change)."""
    from amaranth.back import verilog

    from cosim.boards.cocotb_run import icarus_time_zero_fix, run_cocotb
    from hdl.learner import Learner

    config, seed, obs, cuts = CASES[0]
    population = random_population(np.random.default_rng(0), config.population)
    phases = _with_escape(config, seed, population, _phases(obs, cuts))
    want = reference_phases(config, seed, population, phases)
    case = {
        "seed": seed, "population": population.tolist(),
        "phases": [{"observations": o, "generations": g, "avoid": a, "rates": r} for o, g, a, r in phases],
        "expected": [{"best_index": w["best_index"], "counts": list(w["counts"]), "fails": w["fails"], "score": w["score"],
                      "cycles": w["cycles"], "population": w["population"].tolist()} for w in want],
    }
    case_file = tmp_path / "case.json"
    case_file.write_text(json.dumps(case))
    src = tmp_path / "learner.v"
    src.write_text(icarus_time_zero_fix(verilog.convert(Learner(config), name="learner", emit_src=False)))
    n_tests, _ = run_cocotb(sources=[src], toplevel="learner", test_module="tb_learner", test_dir=TB_DIR,
                            build_name="learner", extra_env={"EHW_LEARNER_CASE": str(case_file)})
    assert n_tests == 1


@pytest.mark.parametrize("tournament", [1, 2, 3, 20])
def test_bank_groups_serve_one_lane_a_cycle(tournament):
    """hdl.learner.bank_groups: in every cycle of a pass, for every slot length C the model can
    give, the rows the lanes ask (and write, the same pattern ROW_LATENCY cycles later) are in
    distinct groups (rows k, k + M, ... in group k)."""
    from ga.genome import N_ROWS
    from hdl.learner import bank_groups

    row_start = 2 * tournament + 1
    for lanes in range(1, 49):
        groups = bank_groups(hg.HardwareGAConfig(population=100, tournament=tournament, lanes=lanes))
        assert lanes <= groups <= N_ROWS
        # C from the shortest slot to 98 cycles past it: beyond, no two slots draw rows in one cycle
        for c in range(hg.slot_cycles(0, tournament), hg.slot_cycles(0, tournament) + N_ROWS + 48):
            for t in range(lanes, lanes + c):  # lane j sees the slot counter j cycles late
                rows = [(t - j) % c - row_start for j in range(lanes)]
                asked = [r % groups for r in rows if 0 <= r < N_ROWS]
                assert len(set(asked)) == len(asked), (lanes, c, t)

"""The learning engine (hdl.learner) against its reference (ga.hardware_ga): populations, best,
counts and cycles, in Amaranth's simulator and (one short case) the generated Verilog in cocotb."""

import json
from pathlib import Path

import numpy as np
import pytest

from ga import hardware_ga as hg
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


def reference_phases(config, seed, population, phases):
    ga = hg.HardwareGA(config, seed, population)
    model = WorldModel()
    out = []
    for obs, generations, *avoid in phases:
        for o in obs:
            model.observe(*o)
        best, counts, cycles = ga.learn(model, generations, avoid=avoid[0] if avoid else None)
        out.append({"best_index": ga.download_index, "escaped": ga.download_index != ga.best_index, "counts": counts, "score": int(ga.scores[ga.download_index]),
                    "cycles": cycles, "population": ga.population.copy(), "n_states": model.n_states})
    return out


# Two regimes of the slot length C = max(N + 2, 2T + 54): breeding-bound (small model) and
# evaluation-bound (T = 1, a model of more than 53 states); high mutation rates so that every
# operator acts; a second phase after more observations continues from the first.
CASES = [
    (hg.HardwareGAConfig(population=7, tournament=2, lanes=3, literal_rate=0.05, output_rate=0.1,
                         switch_rate=0.2, replace_rate=0.1), 123, observations(1, 40, 64), [(25, 2), (40, 1)]),
    (hg.HardwareGAConfig(population=5, tournament=1, lanes=2, literal_rate=0.05, output_rate=0.1,
                         switch_rate=0.2, replace_rate=0.1), 7, observations(2, 200, 256), [(200, 2)]),
]


def _phases(obs, cuts):
    out, last = [], 0
    for end, generations, *avoid in cuts:
        out.append((obs[last:end], generations, *avoid))
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
    return phases[:-1] + [(*phases[-1][:2], (state, motion))]


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
    for g, w in zip(got, want):
        assert g["best_index"] == w["best_index"]
        assert g["counts"] == w["counts"] and g["score"] == w["score"]
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

    from cosim.cocotb_run import icarus_time_zero_fix, run_cocotb
    from hdl.learner import Learner

    config, seed, obs, cuts = CASES[0]
    population = random_population(np.random.default_rng(0), config.population)
    phases = _with_escape(config, seed, population, _phases(obs, cuts))
    want = reference_phases(config, seed, population, phases)
    case = {
        "seed": seed, "population": population.tolist(),
        "phases": [{"observations": o, "generations": g, "avoid": a[0] if a else None} for o, g, *a in phases],
        "expected": [{"best_index": w["best_index"], "counts": list(w["counts"]), "score": w["score"],
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

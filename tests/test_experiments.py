"""The committed experiment scripts (experiments/) run, on a smoke budget."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import numpy as np

EXPERIMENTS = Path(__file__).resolve().parent.parent / "experiments"


def _script(name: str):
    spec = importlib.util.spec_from_file_location(name, EXPERIMENTS / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_online_table_writes_the_table_and_reuses_finished_runs(tmp_path, capsys):
    table = _script("online_table")
    out = tmp_path / "round5.jsonl"
    argv = ["round5", "--seeds", "1,2", "--budget", "60", "--rows", "the default now", "--out", str(out)]
    assert table.main(argv) == 0
    runs = [json.loads(line) for line in out.read_text().splitlines()]
    assert [r["seed"] for r in runs] == [1, 2]
    assert all(r["targets"] < 64 and r["interactions"] in (60, 61) for r in runs)  # the budget (a target may add one)
    assert sum(runs[0]["stops"].values()) == sum(runs[0]["phase_reasons"].values())
    text = (tmp_path / "round5.md").read_text()
    assert "Command: `python experiments/online_table.py round5 --seeds 1,2 --budget 60" in text
    assert "| --distance forward --loop-cycles 1 (the default now) | **" in text
    assert table.main(argv) == 0  # the second time every run is found in the JSON lines
    assert len(out.read_text().splitlines()) == 2
    assert "0 lifetimes to run, 2 in" in capsys.readouterr().err


def test_online_table_lists_the_dropped_rows_with_their_commit(tmp_path):
    table = _script("online_table")
    assert table.main(["round5", "--seeds", "1", "--budget", "100", "--rows", "closest",
                       "--out", str(tmp_path / "t.jsonl")]) == 0
    assert f"(options dropped: run at commit {table.DROPPED_AT})" in (tmp_path / "t.md").read_text()
    assert not (tmp_path / "t.jsonl").read_text()
    for name, (_title, _seeds, _budget, rows) in table.TABLES.items():
        for label, options in rows:
            assert set(options) <= table.known_fields() | table.DROPPED, (name, label)


def test_same_lifetime_compares_field_by_field(tmp_path, capsys):
    same = _script("same_lifetime")
    a = {"interactions": 5, "wall_time_s": 1.0, "config": {"seed": 1, "download": "first"},
         "phases": [{"reason": "loop"}], "hardware": {"reference_evaluator_time_s": 2.0}}
    b = {"interactions": 5, "wall_time_s": 9.0, "config": {"seed": 1},
         "phases": [{"reason": "loop"}], "hardware": {"reference_evaluator_time_s": 3.0}}
    (tmp_path / "a.json").write_text(json.dumps(a))
    (tmp_path / "b.json").write_text(json.dumps(b))
    assert same.main([str(tmp_path / "a.json"), str(tmp_path / "b.json")]) == 0
    b["phases"][0]["reason"] = "crash"
    (tmp_path / "b.json").write_text(json.dumps(b))
    assert same.main([str(tmp_path / "a.json"), str(tmp_path / "b.json")]) == 1
    assert "phases[0].reason: 'loop' vs 'crash'" in capsys.readouterr().out


def test_online_round6_runs_each_variant_and_tabulates(tmp_path, capsys):
    """Each round-6 variant runs a smoke lifetime; the default variant is the plain lifetime."""
    round6 = _script("online_round6")
    out = tmp_path / "r6.jsonl"
    for variant in round6.VARIANTS:
        assert round6.main([variant, "1", "--budget", "120", "--out", str(out)]) == 0
    runs = [json.loads(line) for line in out.read_text().splitlines()]
    assert [r["variant"] for r in runs] == list(round6.VARIANTS)
    assert all(r["interactions"] in (120, 121) and 0 < r["lost"] <= r["interactions"] for r in runs)
    from cosim.online.run import OnlineConfig, make_run

    plain = make_run(OnlineConfig(seed=1, max_interactions=120, loop_blame="leg", fail_rates=False)).run()  # rounds 1-7's rule
    assert runs[0]["interactions"] == plain.interactions and runs[0]["phases"] == len(plain.phases)
    assert round6.main([round6.VARIANTS[0], "1", "--budget", "120", "--out", str(out)]) == 0  # reused
    assert len(out.read_text().splitlines()) == len(round6.VARIANTS)
    capsys.readouterr()
    assert round6.main(["--table", str(out)]) == 0
    assert "| cyclemem_leg | 1: **" in capsys.readouterr().out


def test_online_where_accounts_for_every_interaction(capsys):
    where = _script("online_where")
    assert where.main(["--seed", "1", "--budget", "300"]) == 0
    got = json.loads(capsys.readouterr().out)
    go = got["where_interactions_go"]
    assert got["interactions"] in (300, 301) and sum(go["per_block"]) == got["interactions"]
    # every interaction is in a failed segment or in a leg's rest after its last failure, or after
    # the last failure of the unfinished leg
    assert go["in_failed_segments"] + got["clean"] <= got["interactions"]
    assert got["loops"]["stops"] >= got["loops"]["again_in_lifetime"] >= got["loops"]["again_on_leg"]
    assert got["states"]["met"] >= got["states"]["at_most_5"] >= got["states"]["at_most_2"] > 0
    # 1 -7-> 64 -2-> 0 -0-> 1: the loop is its obstacle pair; the free-space pairs are the reflex's
    assert where.last_cycle([(0, 0), (1, 7), (64, 2), (0, 0)], 1) == ((1, 7),)
    assert where.last_cycle([(0, 0), (64, 2)], 64) == ()


def test_tuning_chooses_the_lowest_median_and_the_deep_grid_is_over_hyper():
    tune = _script("tune_tabular")
    deep = _script("tune_deep")  # importable without the optional extra
    from peers.deep import HYPER, TUNED, tuned_hyper

    tasks, results = [], []
    for point, inter in (({"lr": 1}, [10, 50, 60]), ({"lr": 2}, [30, 31, 32]), ({"lr": 3}, [30, 31, 90])):
        for seed, n in zip((1001, 1002, 1003), inter):
            tasks.append({"method": "dqn/shaped", "seed": seed, "config": {"hyper": point}})
            results.append({"seed": seed, "interactions": n, "targets_reached": 64, "crashes": 0, "cpu_s": 1.0})
    table, chosen = tune.choose(tasks, results, "hyper")
    assert [e["median"] for e in table] == [50, 31, 31]
    assert chosen["dqn/shaped"]["hyper"] == {"lr": 2}  # median 31 beats 50; tie 31-31: the lower mean
    for method in ("dqn", "ppo"):
        points = deep.grid(method)
        assert len(points) == {"dqn": 4, "ppo": 2}[method] and all(p.keys() == HYPER[method].keys() | deep.GRID[method].keys() for p in points)
        for shaping in ("shaped", "unshaped"):
            assert tuned_hyper(method, shaping) == {**HYPER[method], **TUNED.get((method, shaping), {})}


def test_online_round7_runs_each_variant_classes_every_step_and_tabulates(tmp_path, capsys):
    """Each round-7 variant runs a smoke lifetime; the default variant is the plain lifetime, and
    every interaction is classed novel, confirmed or surprise."""
    round7 = _script("online_round7")
    out = tmp_path / "r7.jsonl"
    for variant in round7.VARIANTS:
        assert round7.main([variant, "1", "--budget", "120", "--out", str(out)]) == 0
    runs = [json.loads(line) for line in out.read_text().splitlines()]
    assert [r["variant"] for r in runs] == list(round7.VARIANTS)
    for r in runs:
        assert r["interactions"] in (120, 121)
        assert sum(r["steps"].get(c, 0) for c in ("novel", "confirmed", "surprise")) == r["interactions"]
        assert r["steps"]["novel"] == r["transitions"]  # each model entry was novel once
        assert sum(r["download_trace"].values()) == r["phases"]
    from cosim.online.run import OnlineConfig, make_run

    plain = make_run(OnlineConfig(seed=1, max_interactions=120, loop_blame="leg", fail_rates=False)).run()  # rounds 1-7's rule
    assert runs[0]["interactions"] == plain.interactions and runs[0]["phases"] == len(plain.phases)
    capsys.readouterr()
    assert round7.main(["--table", str(out)]) == 0
    assert "| adaptive | 1: **" in capsys.readouterr().out


def test_online_round7_trace_ends_on_a_small_model():
    import numpy as np

    from ga.world_model import WorldModel

    round7 = _script("online_round7")
    m = WorldModel()
    m.observe(1, 0, 2, False)  # 1 -0-> 2 -0-> 1: a cycle of obstacle states
    m.observe(2, 0, 1, False)
    m.observe(3, 0, 3, True)  # a crash
    tables = np.zeros((2, 256), dtype=np.int64)
    tables[1, 2] = 5  # the second controller leaves 2 by an untried motion
    end = round7.trace_ends(tables, m, np.array([1, 3]), 0)
    names = [[round7.ENDS[e] for e in row] for row in end]
    assert names == [["cycle", "crash"], ["unknown", "crash"]]


def test_online_round8_runs_each_parameter_and_its_cycle_blame_is_the_default(tmp_path, capsys):
    """Round 8's harness: each parameter runs a smoke lifetime; ``blame`` "leg" is the lifetime of
    ``loop_blame`` "leg" (rounds 1-7) and "cycle_now" that of the default ``loop_blame`` "cycle"."""
    round8 = _script("online_round8")
    out = tmp_path / "r8.jsonl"
    params = [["blame=\"leg\""], ["blame=\"cycle_now\""], ["blame=\"cycle_freq\""], ["first2=1"],
              ["at_target=1", "keep=1"], ["every=7", "keep=1"]]
    for ps in params:
        argv = ["default", "1", "--budget", "150", "--out", str(out)]
        for p in ps:
            argv += ["--param", p]
        assert round8.main(argv) == 0
    runs = [json.loads(line) for line in out.read_text().splitlines()]
    assert len(runs) == len(params) and all(r["interactions"] in (150, 151) for r in runs)
    assert runs[4]["reasons"].get("target", 0) == runs[4]["targets"] and runs[5]["reasons"]["periodic"] >= 1
    from cosim.online.run import OnlineConfig, make_run

    for r, rule in ((runs[0], "leg"), (runs[1], "cycle")):
        plain = make_run(OnlineConfig(seed=1, max_interactions=150, loop_blame=rule, fail_rates=False)).run()
        assert (r["interactions"], r["targets"], r["phases"]) == (plain.interactions, plain.targets, len(plain.phases))
    capsys.readouterr()
    assert round8.main(["--table", str(out)]) == 0
    assert "| default first2=1 | 1: **" in capsys.readouterr().out


def test_online_blame_check_counts_where_cycle_stops_are_blamed(capsys):
    check = _script("online_blame_check")
    assert check.main(["1", "200", "leg"]) == 0
    interactions, targets, counts = capsys.readouterr().out.split(" ", 2)
    assert int(interactions) in (200, 201) and "'cycles'" in counts


def test_online_round9_runs_each_rule_and_its_default_is_the_default_lifetime(tmp_path, capsys):
    """Round 9's harness: ``default`` is the lifetime of today's defaults (``loop_blame`` "cycle");
    ``two_if``, ``likely`` and ``crashvote`` run a smoke lifetime, and the baseline is scored in
    every phase."""
    round9 = _script("online_round9")
    out = tmp_path / "r9.jsonl"
    for argv in (["default"], ["default", "--param", "two_if=\"surprise\""], ["likely"], ["crashvote"]):
        assert round9.main([argv[0], "1", "--budget", "150", "--out", str(out), *argv[1:]]) == 0
    runs = [json.loads(line) for line in out.read_text().splitlines()]
    assert len(runs) == 4 and all(150 <= r["interactions"] <= 160 for r in runs)  # crashes and loops may end past it
    assert all(r["baseline"]["phases"] == r["phases"] for r in runs)
    assert all(r["crash_entries"]["crash_entries"] >= r["crash_entries"]["crash_entries_safe_half"] for r in runs)
    from cosim.online.run import OnlineConfig, make_run

    plain = make_run(OnlineConfig(seed=1, max_interactions=150, fail_rates=False)).run()
    assert (runs[0]["interactions"], runs[0]["targets"], runs[0]["phases"]) == (
        plain.interactions, plain.targets, len(plain.phases))
    capsys.readouterr()
    assert round9.main(["--table", str(out)]) == 0
    assert "| likely | 1: **" in capsys.readouterr().out


def test_online_round9_two_cycle_odds_on_a_small_model():
    import numpy as np

    round9 = _script("online_round9")
    outcomes = np.full((256, 8, 4), -1, dtype=np.int64)
    outcomes[1, 0, :2] = [2, 1]  # 1 -0-> 2 half the time (1 -> 1 the other half: no 2-cycle)
    outcomes[2, 0, :4] = [1, 1, 1, 3]  # 2 -0-> 1 three times in four
    tables = np.zeros((2, 256), dtype=np.int64)
    tables[1, 2] = 5  # the second controller leaves 2 by a motion never tried
    odds = round9.two_cycle_odds(tables, outcomes, np.array([1, 2]))
    assert np.allclose(odds, [[0.5 * 0.75, 0.75 * 0.5], [0.0, 0.0]])


def test_online_round10_runs_each_variant(tmp_path, capsys):
    """Round 10's harness: ``likely`` with its 3-cycles, ``vote`` and ``crashfreq`` parameters, and
    ``crashfreq``, run a smoke lifetime; ``likely`` alone is round 9's (same lifetime)."""
    round9, round10 = _script("online_round9"), _script("online_round10")
    out = tmp_path / "r10.jsonl"
    runs_of = (["likely"], ["likely", "--param", "cycles=3"], ["likely", "--param", "vote=1"],
               ["likely", "--param", "crashfreq=1"], ["crashfreq"],
               ["likely", "--param", "cycles=3", "--param", "replace=1"])
    for argv in runs_of:
        assert round10.main([argv[0], "1", "--budget", "150", "--out", str(out), *argv[1:]]) == 0
    runs = [json.loads(line) for line in out.read_text().splitlines()]
    assert len(runs) == len(runs_of) and all(150 <= r["interactions"] <= 160 for r in runs)
    assert round9.main(["likely", "1", "--budget", "150", "--out", str(tmp_path / "r9.jsonl")]) == 0
    r9 = json.loads((tmp_path / "r9.jsonl").read_text())
    same = ("interactions", "targets", "phases", "generations", "legs", "steps", "failure_classes")
    assert [r9[k] for k in same] == [runs[0][k] for k in same]
    capsys.readouterr()
    assert round10.main(["--table", str(out)]) == 0
    assert "| likely cycles=3 | 1: **" in capsys.readouterr().out


def test_online_round9_two_cycle_odds_is_the_4d_gather():
    """Round 9's ``two_cycle_odds`` (a per-phase table of outcome shares since round 10) gives the
    values of its first form (a (P, n, H, H) gather of the kept outcomes), to the bit."""
    import numpy as np

    round9 = _script("online_round9")
    rng = np.random.default_rng(0)
    outcomes = np.full((256, 8, 8), -1, dtype=np.int64)
    for s in rng.integers(0, 40, 150):
        k = int(rng.integers(1, 9))
        outcomes[s, rng.integers(8), :k] = rng.integers(0, 40, k)
    tables = rng.integers(0, 8, (50, 256))
    states = np.unique(rng.integers(1, 40, 25))
    rows = np.arange(50)[:, None, None]
    kept = (outcomes >= 0).sum(axis=2)
    o1 = outcomes[states[None, :], tables[:, states]]
    n1 = kept[states[None, :], tables[:, states]]
    s2 = np.where(o1 >= 0, o1, 0)
    o2, n2 = outcomes[s2, tables[rows, s2]], kept[s2, tables[rows, s2]]
    back = (o2 == states[None, :, None, None]).sum(axis=3) / np.maximum(n2, 1)
    first = (((o1 >= 0) & (o1 != states[None, :, None])) * back).sum(axis=2) / np.maximum(n1, 1)
    assert np.array_equal(round9.two_cycle_odds(tables, outcomes, states), first)


def test_online_round10_cycles_on_a_small_model():
    import numpy as np

    round9, round10 = _script("online_round9"), _script("online_round10")
    outcomes = np.full((256, 8, 4), -1, dtype=np.int64)
    outcomes[1, 0, :2] = [2, 1]  # 1 -0-> 2 half the time
    outcomes[2, 0, :4] = [1, 1, 1, 3]  # 2 -0-> 1 three times in four, 2 -0-> 3 once
    outcomes[3, 0, :1] = [1]
    shares = round9.back_shares(outcomes)
    tables = np.zeros((2, 256), dtype=np.int64)
    tables[1, 2] = 5  # the second controller leaves 2 by a motion never tried
    states, factors = round10.likely_cycles(shares, [1, 2], 2)
    assert states.tolist() == [[1, 2], [2, 1]]  # the 2-cycles, as round 9's odds count them
    assert np.allclose(round10.cycle_odds(tables, states, factors),
                       round9.two_cycle_odds(tables, outcomes, np.array([1, 2])).sum(axis=1))
    states, factors = round10.likely_cycles(shares, [1, 2], 3)
    assert states.tolist() == [[1, 2, 3], [2, 3, 1]]  # 1 -> 2 -> 3 -> 1 from each obstacle start
    assert np.allclose(round10.cycle_odds(tables, states, factors), [2 * 0.5 * 0.25 * 1.0, 0.0])


def test_online_round10_terms_prints_the_fitness_gap_by_term(capsys):
    terms = _script("online_round10_terms")
    assert terms.main(["1", "150"]) == 0
    out = capsys.readouterr().out
    assert "fitness gap: distance term" in out and "untried obstacle entries" in out


def test_online_detector_stops_counts_the_false_alarms_of_a_controller_that_never_fails(capsys):
    stops = _script("online_detector_stops")
    from cosim.online.run import OnlineConfig

    run, found_default = stops.baseline_lifetime(OnlineConfig(seed=1, n_targets=6))
    assert run.targets == 6 and len(run.phases) == sum(found_default.values()) > 0
    assert set(found_default) == {"loop:cycles"}  # the one-round cycle stop is what fires
    run, found = stops.baseline_lifetime(OnlineConfig(seed=1, n_targets=6, loop_cycles=0))
    assert "loop:cycles" not in found
    assert stops.main(["--seeds", "1", "--set", "n_targets=2", "--cycles"]) == 0
    total = json.loads(capsys.readouterr().out.splitlines()[-1])
    assert total["seeds"] == "1" and "cycles" in total
    assert stops.main(["--seeds", "x"]) == 2
    assert capsys.readouterr().err.startswith("error: ")
    # the pose rule (dropped) fires less: a round of net rotation 22.5 degrees is not a loop
    run, posed = stops.baseline_lifetime(OnlineConfig(seed=1, n_targets=6), pose_deg=1.0)
    assert run.targets == 6 and 0 < posed["loop:cycles"] < sum(found_default.values())
    assert stops.main(["--seeds", "1", "--learn", "--budget", "150", "--pose-deg", "1"]) == 0
    line = json.loads(capsys.readouterr().out)
    assert line["pose_deg"] == 1.0 and line["interactions"] in range(150, 152)


def test_online_round11_distance_credit_trace_form_is_the_vectorised_form():
    """Round 11's credited distance: the trace form (the pseudo-code, each visited state earning its
    credit) equals the per-state sum, and with the SPEC's parameters both are SPEC section 7's
    distance."""
    import numpy as np

    from ga.evaluator import evaluate_tables
    from ga.world_model import WorldModel

    round11 = _script("online_round11")
    rng = np.random.default_rng(3)
    model = WorldModel()
    pool = rng.choice(256, 40, replace=False)  # free-space and obstacle states
    for _ in range(200):
        model.observe(int(rng.choice(pool)), int(rng.integers(8)), int(rng.choice(pool)), rng.random() < 0.1)
    tables = rng.integers(0, 8, (20, 256))
    for untried, obstacle_any, away in ((0.0, False, False), (1.0, False, False), (0.5, True, False), (0.5, True, True)):
        vec = round11.credited_distance(tables, model, "forward", untried, obstacle_any, away)
        assert vec.tolist() == [round11.trace_distance(t, model, "forward", untried, obstacle_any, away)
                                for t in tables]
    assert round11.credited_distance(tables, model, "forward").tolist() == evaluate_tables(
        tables, model, "forward").distance.tolist()
    assert (round11.credited_distance(tables, model, "forward", 1.0) > evaluate_tables(
        tables, model, "forward").distance).any()  # an untried forward motion earns now


def test_online_round11_runs_the_distance_rules(tmp_path, capsys):
    """Round 11's ``distance`` with the SPEC's parameters is the default lifetime; each revised rule
    runs a smoke lifetime and the terms instrument prints a row per rule."""
    round11 = _script("online_round11")
    out = tmp_path / "r11.jsonl"
    runs_of = (["default"], ["distance"], ["distance", "--param", "untried=1"],
               ["distance", "--param", "obstacle_any=1", "--param", "w_distance=0.02"])
    for argv in runs_of:
        assert round11.main([argv[0], "1", "--budget", "150", "--out", str(out), *argv[1:]]) == 0
    runs = [json.loads(line) for line in out.read_text().splitlines()]
    assert len(runs) == len(runs_of) and all(150 <= r["interactions"] <= 160 for r in runs)
    same = ("interactions", "targets", "phases", "generations", "legs", "steps", "failure_classes")
    assert [runs[0][k] for k in same] == [runs[1][k] for k in same]
    capsys.readouterr()
    assert round11.main(["--table", str(out)]) == 0
    assert "| distance untried=1 | 1: **" in capsys.readouterr().out
    assert _script("online_round11_terms").main(["1", "150", "distance", "untried=1"]) == 0
    assert "| obstacle_any=1 untried=0.5 |" in capsys.readouterr().out


def test_online_round12_mirrored_writes_reach_the_board_and_the_host_copy(tmp_path, capsys):
    """Round 12: the mirrored observations go to the board and to the host's copy alike (the same
    model after a lifetime); with no mirror rule the lifetime is ``default``'s, field by field."""
    from cosim.online.run import OnlineConfig, make_run

    round12 = _script("online_round12")
    assert round12.mirrored(0b000010 | 1 << 6, 4, 0b000100 | 3 << 6, False) == (0b000100 | 3 << 6, 5, 0b000010 | 1 << 6, False)
    assert round12.mirrored(0b001000, 6, 0b001001, True) == (0b010000, 7, 0b010000, True)
    for variant, params in (("mirror_fill", {}), ("mirror_crash", {}), ("mirror_full", {"states": "known"}),
                            ("mode", {"pool": 1})):
        config = OnlineConfig(seed=1, max_interactions=150, fail_rates=False)
        base = make_run(config)
        round12.Round12.variant, round12.Round12.params = variant, {**round12.DEFAULT_PARAMS, **params}
        run = round12.Round12(config, base.controller, base.evaluator)
        run.run()
        assert run.evaluator.model == run.mirror
        figures = run.extra_figures()["mirror"]
        assert figures["mirrored_entries"] > 0 and figures["real_pairs"] <= figures["model_transitions"]
        if params.get("states") == "known":  # no mirrored write adds a state to S
            assert figures["states_never_visited"] == 0
        if variant == "mode":  # every non-crash entry the robot executed holds its most frequent outcome
            assert figures["mode_written"] > 0
            for (s, a), tally in run.tallies.items():
                if run.real[s, a] and not run.mirror.crash[s, a]:
                    assert run.mirror.next_state[s, a] == max(tally, key=tally.get)
    out = tmp_path / "r12.jsonl"
    for argv in (["default"], ["mirror", "--param", 'mirror=""'], ["mirror_fill"]):
        assert round12.main([argv[0], "1", "--budget", "150", "--out", str(out), *argv[1:]]) == 0
    runs = [json.loads(line) for line in out.read_text().splitlines()]
    same = ("interactions", "targets", "phases", "generations", "legs", "steps", "failure_classes")
    assert [runs[0][k] for k in same] == [runs[1][k] for k in same]
    capsys.readouterr()
    assert round12.main(["--table", str(out)]) == 0
    assert "| mirror_fill | 1: **" in capsys.readouterr().out


def test_online_round12_symmetry_check_scores_the_predictions(capsys):
    """Round 12's symmetry check: on a world that is its own mirror image (each outcome followed by
    the mirrored pair's mirrored outcome) the mirrored prediction is as good as the real one."""
    from ga.motions import MIRROR_MOTION, MIRROR_STATE, make_state

    sym = _script("online_round12_symmetry")
    s, s2 = make_state(0b000010, 1), make_state(0b000110, 0)  # front-left obstacle, target left
    obs = []
    for _ in range(3):
        obs.append((s, 4, s2, False))
        obs.append((int(MIRROR_STATE[s]), int(MIRROR_MOTION[4]), int(MIRROR_STATE[s2]), False))
    counts = sym.scores(obs)
    assert counts["observations"] == 6 and counts["real_known"] == 4 and counts["mirror_known"] == 5
    assert counts["both_known"] == 4 and counts["both_real_right"] == counts["both_mirror_right"] == 4
    assert counts["both_pooled_mode_right"] == 4
    assert sym.main(["--random", "300", "--seed", "1"]) == 0
    line = json.loads(capsys.readouterr().out)
    assert line["observations"] <= 300 and line["real_known"] >= line["real_right"]


def test_online_round14_failure_marks_the_rates_and_the_bandit_escape(tmp_path, capsys):
    """Round 14: a failure marks the last ``horizon`` pairs of its execution phase (each once), a
    target clears the phase's pairs; ``failrate`` subtracts the rates of the chosen motions; the
    bandit escape picks the offered motion with the lowest rate; ``default`` is the plain lifetime."""
    from cosim.online.run import OnlineConfig, make_run

    r14 = _script("online_round14")
    config = OnlineConfig(seed=1, max_interactions=150, fail_rates=False)
    base = make_run(config)
    r14.Round14.variant, r14.Round14.params = "failrate", {**r14.DEFAULT_PARAMS, "horizon": 2}
    run = r14.Round14(config, base.controller, base.evaluator)
    run.open_pairs = [(65, 0), (66, 1), (65, 0), (67, 2)]
    run.judge_failure()
    assert run.failed[67, 2] == 1 and run.failed[65, 0] == 1 and run.failed[66, 1] == 0 and not run.open_pairs
    run.executed[65, 0], run.executed[67, 2] = 3, 1
    rates = run.rates()
    assert rates[65, 0] == (1 + 0.3) / 4 and rates[67, 2] == (1 + 0.3) / 2 and rates[1, 1] == 0.3
    assert r14.thrash([10, 500])["thrash_legs"] == 1
    # the bandit escape: motion 3 has the lowest rate of the offered ones, the blamed 0 is excluded
    run.failed[65] = [0, 5, 5, 0, 5, 5, 5, 5]
    run.executed[65] = [9, 5, 5, 9, 5, 5, 5, 5]
    from ga.truth_table import truth_tables
    pop = base.ga.ask()[:40]
    fitness = np.linspace(0.0, 1.0, len(pop))
    motions = truth_tables(pop, reflex=True)[:, 65]
    i, _ = run.escape_download(pop, fitness, (65, 0))
    offered = sorted(set(motions.tolist()) - {0})
    best = min(offered, key=lambda m: run.rates()[65, m])
    assert motions[i] == best and fitness[i] == fitness[motions == best].max()
    out = tmp_path / "r14.jsonl"
    for variant in ("default", "failrate", "bandit"):
        assert r14.main([variant, "1", "--budget", "150", "--out", str(out)]) == 0
    runs = [json.loads(line) for line in out.read_text().splitlines()]
    assert runs[0]["thrash"]["baseline"] > 0 and runs[0]["executed"] == 150
    assert runs[0]["downloads"]["n"] == runs[0]["phases"] + 1 and runs[0]["downloads"]["most_targets"] >= 0
    capsys.readouterr()
    assert r14.main(["--table", str(out)]) == 0
    assert "| failrate | 1-1 (1) |" in capsys.readouterr().out


def test_online_round15_default_is_the_lifetime_and_rates_change_the_marks(tmp_path, capsys):
    """Round 15: ``default`` is the main code's lifetime (failure rates on); ``rates`` with another
    prior writes other codes, and ``w`` scales the fail counts the host fitness sees."""
    from cosim.online.run import OnlineConfig, make_run

    r15 = _script("online_round15")
    out = tmp_path / "r15.jsonl"
    assert r15.main(["default", "1", "--budget", "150", "--out", str(out)]) == 0
    assert r15.main(["rates", "1", "--budget", "150", "--param", "w=2", "--param", "prior_code=12",
                     "--out", str(out)]) == 0
    runs = [json.loads(line) for line in out.read_text().splitlines()]
    plain = make_run(OnlineConfig(seed=1, max_interactions=150, rate_mirror=False, progress_weight=0.0)).run()  # round 15's codes
    assert (runs[0]["interactions"], runs[0]["phases"]) == (plain.interactions, len(plain.phases))
    assert runs[1]["params"] == {"w": 2, "prior_code": 12}
    marks = r15.Marks(horizon=8, prior_code=12)
    assert marks.codes()[0, 0] == 12 and marks.changes()[0] == (0, 0, 12)
    board = make_run(OnlineConfig(seed=1)).evaluator
    board.rates[:] = 200
    pop = make_run(OnlineConfig(seed=1)).ga.ask()[:5]
    board.observe(65, 0, 66, False)
    assert (r15.Weighted(board, 2.0).evaluate(pop).fails == 2 * board.evaluate(pop).fails).all()
    capsys.readouterr()
    assert r15.main(["--table", str(out)]) == 0
    assert "| rates prior_code=12 w=2 | 1-1 (1) |" in capsys.readouterr().out


def test_online_round16_mirror_marks_are_the_main_code_and_the_other_marks_differ(tmp_path, capsys):
    """Round 16: ``default`` is round 15's lifetime (own counts); ``marks pool_mirror=1`` is the main
    code's default (``rate_mirror``), phase for phase; decay and the failure kinds' weights change
    the codes; ``w_dist`` scales the distance counts the host fitness sees."""
    from cosim.online.run import OnlineConfig, make_run

    r16 = _script("online_round16")
    out = tmp_path / "r16.jsonl"
    assert r16.main(["default", "1", "--budget", "300", "--out", str(out)]) == 0
    assert r16.main(["marks", "1", "--budget", "300", "--param", "pool_mirror=1", "--out", str(out)]) == 0
    runs = [json.loads(line) for line in out.read_text().splitlines()]
    own = make_run(OnlineConfig(seed=1, max_interactions=300, rate_mirror=False, progress_weight=0.0)).run()
    pooled = make_run(OnlineConfig(seed=1, max_interactions=300, progress_weight=0.0)).run()
    assert (runs[0]["interactions"], runs[0]["phases"]) == (own.interactions, len(own.phases))
    key = ("interactions", "targets", "phases")
    assert [runs[1][k] for k in key] == [pooled.interactions, pooled.targets, len(pooled.phases)]
    assert [p["state"] for p in own.phases] != [p["state"] for p in pooled.phases]
    marks = r16.Marks(horizon=8, decay=0.5, weights={"crash": 1.0, "loop": 0.25, "timeout": 1.0})
    marks.executed_pair(65, 0, reached=False)
    marks.reason = "loop"
    marks.failure()  # the counts halve, then the loop marks a quarter
    assert marks.failed[65, 0] == 0.25 and marks.codes()[65, 0] == round((250 * 0.25 + 25) / 1.5)
    marks.executed_pair(65, 0, reached=False)
    marks.reason = "crash"
    marks.failure()  # the old counts halve first
    assert marks.failed[65, 0] == 1.125 and marks.executed[65, 0] == 0.75
    board = make_run(OnlineConfig(seed=1)).evaluator
    board.observe(65, 0, 66, False)
    pop = make_run(OnlineConfig(seed=1)).ga.ask()[:5]
    assert (r16.Weighted(board, 0.5, "distance").evaluate(pop).distance == 0.5 * board.evaluate(pop).distance).all()
    capsys.readouterr()
    assert r16.main(["--table", str(out)]) == 0
    assert "| marks pool_mirror=1 | 1-1 (1) |" in capsys.readouterr().out


def test_online_round17_default_and_plain_pool_are_the_main_code_and_the_pools_add_counts(tmp_path, capsys):
    """Round 17: ``default`` and ``pool`` without parameters are the main code's lifetime (mirror
    pooled codes); the neighbour pools lend counts between obstacle states only, a cycle stop marks
    the cycle, the credit lowers a rate, the visit weight raises a busy state's codes."""
    from cosim.online.run import OnlineConfig, make_run
    from ga.motions import X_BACK

    r17 = _script("online_round17")
    out = tmp_path / "r17.jsonl"
    assert r17.main(["default", "1", "--budget", "300", "--out", str(out)]) == 0
    assert r17.main(["pool", "1", "--budget", "300", "--param", "pool_back=0", "--out", str(out)]) == 0
    runs = [json.loads(line) for line in out.read_text().splitlines()]
    main_code = make_run(OnlineConfig(seed=1, max_interactions=300, progress_weight=0.0)).run()  # before round 18
    key = ("interactions", "targets", "phases")
    assert [runs[0][k] for k in key] == [runs[1][k] for k in key] \
        == [main_code.interactions, main_code.targets, len(main_code.phases)]
    params = {**r17.DEFAULT_PARAMS, "pool_back": 1.0}
    marks = r17.Marks(params)
    s = 1 | 1 << X_BACK  # front and back obstacle bits; its back-flipped neighbour is state 1
    marks.executed_pair(s, 0, reached=False)
    marks.failure()
    assert marks.codes()[1, 0] == marks.codes()[s, 0] == round((250 * 2 + 25) / 3)  # its mirror is itself
    lone = r17.Marks(params)
    lone.executed_pair(1 << X_BACK, 0, reached=False)  # back bit alone: its neighbour is free space
    lone.failure()
    assert lone.codes()[0, 0] == 25
    cyc = r17.Marks({**r17.DEFAULT_PARAMS, "mark_cycle": 1})
    for pair in ((5, 0), (6, 2), (7, 3)):
        cyc.executed_pair(*pair, reached=False)
    cyc.cycle, cyc.reason = [(6, 2), (7, 3)], "loop"
    cyc.failure()
    assert cyc.failed[5, 0] == 0 and cyc.failed[6, 2] == cyc.failed[7, 3] == 1
    paid = r17.Marks({**r17.DEFAULT_PARAMS, "credit": 2.0})
    paid.executed_pair(5, 0, reached=True)
    assert paid.executed[5, 0] == 3
    busy = r17.Marks({**r17.DEFAULT_PARAMS, "visit_gamma": 1.0})
    for _ in range(3):
        busy.executed_pair(5, 0, reached=False)
    busy.executed_pair(9, 0, reached=False)
    busy.failure()
    assert busy.codes()[5, 1] == 38 and busy.codes()[9, 1] == 13  # 25 x 1.5, 25 x 0.5, halves up
    capsys.readouterr()
    assert r17.main(["--table", str(out)]) == 0
    assert "| pool pool_back=0 | 1-1 (1) |" in capsys.readouterr().out


def test_online_round18_variants_and_the_probe(tmp_path, capsys):
    """Round 18: ``default`` is the main code's lifetime, and so is the oracle when it may only take
    the plain download (its look-aheads run on a copy of the world and leave the real one alone);
    ``progress_codes`` is the main code with ``progress_weight``; the probe's marks rebuilt from its
    log are the lifetime's own."""
    import numpy as np

    from cosim.online.run import OnlineConfig, make_run
    from sim_world.baseline import baseline_table

    r18 = _script("online_round18")
    out = tmp_path / "r18.jsonl"
    assert r18.main(["default", "1", "--budget", "300", "--out", str(out)]) == 0
    assert r18.main(["oracle", "1", "--budget", "300", "--param", "oracle_k=1", "--out", str(out)]) == 0
    assert r18.main(["progress_codes", "1", "--budget", "300", "--param", "progress_w=3", "--out", str(out)]) == 0
    runs = [json.loads(line) for line in out.read_text().splitlines()]
    key = ("interactions", "targets", "phases", "failures")
    main_code = make_run(OnlineConfig(seed=1, max_interactions=300, progress_weight=0.0)).run()  # before round 18
    assert [runs[0][k] for k in key] == [runs[1][k] for k in key]
    assert runs[0]["phases"] == len(main_code.phases) and runs[1]["oracle"]["changed"] == 0
    progress = make_run(OnlineConfig(seed=1, max_interactions=300, progress_weight=3.0)).run()
    assert runs[2]["phases"] == len(progress.phases) and runs[2]["targets"] == progress.targets
    assert runs[2]["phases"] != runs[0]["phases"] or runs[2]["targets"] != runs[0]["targets"]
    capsys.readouterr()
    assert r18.main(["--table", str(out)]) == 0
    assert "| progress_codes progress_w=3 | 1-1 (1) |" in capsys.readouterr().out

    probe = _script("online_round18_probe")
    path = probe.collect(1, every=1, repeats=1, budget=400, out=tmp_path)
    data = np.load(path)
    assert len(data["time"]) >= 2 and (data["tables"][:, 1] == baseline_table()).all()
    for i in range(len(data["time"])):
        rec = {k: data[k][i] for k in ("time", "failed", "executed")}
        rec["log"], rec["fail_at"] = data["log"], data["fail_at"]
        failed, executed = probe.marks_at(rec)
        assert (failed == rec["failed"]).all() and (executed == rec["executed"]).all()
    table = probe.score([1], only="return 8 alone", folder=tmp_path)
    assert table.count("\n") == 2 and "| return 8 alone |" in table

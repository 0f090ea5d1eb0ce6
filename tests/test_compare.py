"""cosim.compare.run and cosim.compare.sweep: the table, the ratio, the plot, the fixed controller under a
blinded sensor, the executors (a process pool and a small local Dask cluster give the same
table) and the cache that lets a sweep resume."""

from __future__ import annotations

import json
from concurrent.futures import Executor, ProcessPoolExecutor

import numpy as np
import pytest

from base.errors import UserError
from cosim.compare.run import (
    DEFAULT_METHODS,
    METHODS,
    build_report,
    fixed_controller_adaptation,
    make_tasks,
    markdown,
    seed_provenance,
    write_boxplot,
    run_task,
    write_plot,
)
from cosim.compare.sweep import Cache, executor, run_sweep
from ga.genome import hex_from_rows
from ga.operators import random_population



def main(argv) -> int:
    """``ehw compare ARGV`` (its exit status)."""
    from cosim.cli.main import main as ehw

    return ehw(["compare", *argv])

@pytest.fixture(autouse=True)
def _in_tmp(tmp_path, monkeypatch):
    """Each test in a fresh working directory (the comparison's results/compare/ is there)."""
    monkeypatch.chdir(tmp_path)


def _fake(interactions, generations, pop, targets=64):
    return {"interactions": interactions, "generations": generations,
            "genetic_operations": generations * pop, "world_states": 100, "transitions": 300,
            "targets_reached": targets, "crashes": 3, "cpu_s": 1.5,
            "target_interactions": np.linspace(1, interactions, targets).round().astype(int).tolist()}


def test_report_medians_ranges_and_ratio(tmp_path):
    results = {
        "online": {1: _fake(10_000, 400, 500), 2: _fake(12_000, 500, 500), 3: _fake(20_000, 600, 500)},
        "offline": {1: _fake(3_000_000, 300, 20), 2: _fake(2_400_000, 250, 20), 3: _fake(4_000_000, 280, 20)},
        "q-learning/shaped": {1: _fake(7_000, 0, 0), 2: _fake(100_000, 0, 0, targets=40), 3: _fake(9_000, 0, 0)},
    }
    report = build_report(results, "default", [1, 2, 3])
    on = report["methods"]["online"]["interactions"]
    assert on == {"median": 12_000.0, "q1": 11_000.0, "q3": 16_000.0, "min": 10_000, "max": 20_000}
    assert report["methods"]["online"]["interactions_per_seed"] == {1: 10_000, 2: 12_000, 3: 20_000}
    assert report["interaction_ratio"]["of_medians"] == 3_000_000 / 12_000
    assert report["interaction_ratio"]["per_seed"] == [300.0, 200.0, 200.0]
    q = report["methods"]["q-learning/shaped"]
    assert q["reached_64"] == 2 and q["capped"] == {2: 40}
    text = markdown(report)
    assert "| on-line model-based | 3/3 | 12,000 (10,000-20,000) | 11,000-16,000 | - | 3 |" in text  # no limit: "-"
    assert "| off-line model-free | 3/3 | 3,000,000 (2,400,000-4,000,000) |" in text
    assert "| Q-learning, shaped | 2/3 | 9,000 (7,000-100,000) |" in text
    assert "| paper, on-line | yes | 12,280 |" in text and "| paper, off-line | yes | 3,283,269 |" in text
    assert "Q-learning, shaped: seed 2 at 40" in text
    assert "**250**" in text
    png = write_plot(report, tmp_path / "compare.png")
    assert png.stat().st_size > 10_000
    box = write_boxplot(report, tmp_path / "compare_box.png")
    assert box.stat().st_size > 10_000


def test_the_table_says_which_seeds_chose_the_settings(monkeypatch):
    results = {"online": {1: _fake(9_000, 300, 500), 281: _fake(5_000, 300, 500)},
               "q-learning/shaped": {1001: _fake(7_000, 0, 0)}}
    report = build_report(results, "default", [1, 281, 1001])
    report["seed_provenance"] = seed_provenance(results, [1, 281, 1001])
    text = markdown(report)
    assert "## Seeds: which chose the settings" in text and "Reported: seeds 1, 281, 1001." in text
    online, tabular = report["seed_provenance"]
    assert "seeds 1..280, 1001..1005" in online and "**reported seeds 1, 1001 were among them**" in online
    assert "1001..1005" in tabular and "**reported seeds 1001 were among them**" in tabular
    assert "not tuned" not in tabular
    import peers.tabular

    monkeypatch.delitem(peers.tabular.TUNED, ("dyna-q+", "shaped"))
    assert "not tuned, `peers.tabular.DEFAULTS`: Dyna-Q+, shaped" in seed_provenance({"dyna-q+/shaped": {}}, [1])[0]
    clean = seed_provenance(results, [281, 282])
    assert all("none of the reported seeds was" in line for line in clean)


def test_fixed_controller_under_a_blinded_sensor_is_counted_and_blind():
    from ga.genome import rows_from_hex
    from ga.truth_table import truth_tables
    from sim_world.course import run_course
    from sim_world.world import DEFAULT_NOISE, World

    genome = hex_from_rows(random_population(np.random.default_rng(0), 1)[0])
    bit, window, limit = 0, 2, 50
    res = fixed_controller_adaptation(genome, "empty", seed=1, bit=bit, after=3, window=window, max_leg_steps=limit)
    assert res["targets"] <= window and res["interactions"] <= window * limit
    if res["targets"] < window:
        assert res["interactions_for_next_targets"] is None
    # The sensor really was blinded: no state it met has the bit set ...
    assert res["states_with_bit"] == 0
    # ... while the same controller in the same world without the fault does see it.
    world = World("empty", noise=DEFAULT_NOISE, seed=1)
    seen = run_course(world, truth_tables(rows_from_hex(genome), reflex=True), limit, n_targets=window,
                      start=2, stop_on_crash=False)
    assert sum(1 for s in seen.states if s >> bit & 1) > 0


def test_methods_and_tasks():
    assert set(DEFAULT_METHODS) == set(METHODS) - {"dqn", "ppo"}
    tasks = make_tasks(["baseline", "q-learning"], [1, 2], arena="default", out="x", shapings=("shaped",))
    assert [(t["method"], t["seed"]) for t in tasks] == [("baseline", 1), ("baseline", 2),
                                                         ("q-learning/shaped", 1), ("q-learning/shaped", 2)]
    assert tasks[2]["config"]["learner"]["alpha"] > 0  # the learner's config is in the cache key


def test_online_cache_key_is_the_effective_config(monkeypatch):
    """The on-line row's key holds every default, so a changed default is a new lifetime."""
    import dataclasses

    import cosim.online.config as oc
    from cosim.compare.sweep import task_key

    def key(**online):
        return task_key(make_tasks(["online"], [1], arena="default", out="x", online=online)[0])

    default_cycles = oc.OnlineConfig().loop_cycles
    assert key() == key(loop_cycles=default_cycles)  # the same lifetime, the same key
    assert key() != key(loop_cycles=default_cycles + 1)
    before = key()
    assert set(before["config"]["online"]) == {f.name for f in dataclasses.fields(oc.OnlineConfig)} - {"seed", "arena"}

    @dataclasses.dataclass(frozen=True)
    class NewerDefaults(oc.OnlineConfig):
        loop_window: int = oc.OnlineConfig().loop_window + 1

    monkeypatch.setattr(oc, "OnlineConfig", NewerDefaults)
    assert key() != before


def test_command_line_errors_are_one_line(capsys):
    assert main(["--methods", "baseline,sarsa"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: --methods: unknown method(s) sarsa") and err.count("\n") == 1
    assert main(["--shaping", "dense"]) == 2
    assert capsys.readouterr().err.startswith("error: --shaping")


def test_online_options_are_typed_checked_and_reported():
    from cosim.compare.run import online_options

    assert online_options(["distance_rule=covered", "loop_cycles=0", "escape=false"]) == \
        {"distance_rule": "covered", "loop_cycles": 0, "escape": False}
    with pytest.raises(ValueError, match="--distance"):
        online_options(["distance_rule=backward"])
    with pytest.raises(UserError, match="KEY=VALUE"):
        online_options(["no_such_field=1"])
    report = build_report({"online": {1: _fake(9_000, 300, 500)}}, "default", [1])
    report.update(online_distance_rule="covered", online_options={"distance_rule": "covered", "loop_cycles": 0})
    text = markdown(report)
    assert "first reading" in text and "`loop_cycles=0`" in text


# -- the executors and the cache -----------------------------------------------------------------

SMALL = ["--seeds", "2", "--methods", "baseline,q-learning", "--shaping", "shaped",
         "--max-interactions", "800", "--jobs", "2", "--no-planner-limit"]


def _figures(path):
    report = json.loads((path / "compare.json").read_text())
    return {row: {s: (r["interactions"], r["targets_reached"], r.get("crashes"), r["target_interactions"])
                  for s, r in per.items()} for row, per in report["per_seed"].items()}


def test_same_table_on_a_process_pool_and_a_local_dask_cluster(tmp_path):
    assert main(SMALL + ["--out", str(tmp_path / "pool"), "--cache", "pool_cache"]) == 0
    assert main(SMALL + ["--out", str(tmp_path / "dask"), "--cache", "dask_cache", "--cluster", "local"]) == 0
    pool, dask = _figures(tmp_path / "pool"), _figures(tmp_path / "dask")
    assert pool == dask
    assert set(pool) == {"baseline", "q-learning/shaped"}
    assert pool["q-learning/shaped"]["1"][0] == 800  # capped at the given interactions
    assert "Dask cluster local" in (tmp_path / "dask" / "compare.md").read_text()
    assert (tmp_path / "pool" / "compare.png").exists() and (tmp_path / "pool" / "compare_box.png").exists()


class _Refuse(Executor):
    """An executor that must not be asked for anything (everything is in the cache)."""

    def submit(self, fn, *args, **kwargs):
        raise AssertionError(f"submitted {args}")


def test_a_sweep_resumes_from_its_cache(tmp_path):
    tasks = make_tasks(["q-learning"], [1, 2], arena="default", out=str(tmp_path), shapings=("shaped",),
                       max_interactions=400)
    cache = Cache(tmp_path / "cache")
    with ProcessPoolExecutor(2) as pool:
        first = run_sweep(run_task, tasks, pool, cache)
    assert [r["interactions"] for r in first] == [400, 400]
    seen = []
    again = run_sweep(run_task, tasks, _Refuse(), cache, on_result=lambda t, r, cached: seen.append(cached))
    assert again == first and seen == [True, True]
    # a new seed runs alone; a changed config is another key
    more = make_tasks(["q-learning"], [1, 2, 3], arena="default", out=str(tmp_path), shapings=("shaped",),
                      max_interactions=400)
    with executor(1) as pool:
        grown = run_sweep(run_task, more, pool, cache, on_result=lambda t, r, cached: seen.append(cached))
    assert grown[:2] == first and seen[2:] == [True, True, False]
    other = dict(more[0], config={**more[0]["config"], "max_interactions": 300})
    assert cache.get(other) is None and cache.path(other) != cache.path(more[0])


def test_slow_rows_on_fewer_seeds_are_said_so(tmp_path, capsys):
    args = ["--seeds", "2", "--methods", "baseline,q-learning", "--shaping", "shaped", "--jobs", "1",
            "--max-interactions", "300", "--out", str(tmp_path)]
    assert main(args + ["--limit-seeds", "q-learning/shaped=1"]) == 0
    report = json.loads((tmp_path / "compare.json").read_text())
    assert sorted(report["per_seed"]["baseline"]) == ["1", "2"]
    assert sorted(report["per_seed"]["q-learning/shaped"]) == ["1"]
    assert "Rows on fewer seeds (the first ones of the range; CPU at hand): Q-learning, shaped: 1." in \
        (tmp_path / "compare.md").read_text()
    assert main(args + ["--limit-seeds", "sarsa=1"]) == 2
    assert capsys.readouterr().err.startswith("error: --limit-seeds")

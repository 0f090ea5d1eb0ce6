"""The committed experiment scripts (experiments/) run, on a smoke budget."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path


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



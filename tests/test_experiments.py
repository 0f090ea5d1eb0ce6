"""The scripts that stay in experiments/ (experiments/README.md): each stands alone and runs.

Each test takes seconds: a smoke budget, or the script's pure functions. The research scripts of
rounds 6-18 are at the tag ``research/round-18``; tests/test_golden_lifetime.py pins today's
default lifetime in their place.
"""

from __future__ import annotations

import ast
import importlib.util
import json
from pathlib import Path

EXPERIMENTS = Path(__file__).resolve().parent.parent / "experiments"
PACKAGES = {"base", "cosim", "ga", "sim_world", "hdl", "peers", "formal", "benchmarks"}


def _script(name: str):
    spec = importlib.util.spec_from_file_location(name, EXPERIMENTS / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_every_script_stands_alone_and_all_fit_in_1500_lines():
    """A script imports the packages (and the standard library, numpy), never another script,
    and finds them installed (`make venv`), with no sys.path edits."""
    scripts = sorted(EXPERIMENTS.glob("*.py"))
    assert scripts and sum(len(p.read_text().splitlines()) for p in scripts) < 1500
    names = {p.stem for p in scripts}
    for path in scripts:
        text = path.read_text()
        assert "sys.path" not in text and "spec_from_file_location" not in text, path.name
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, ast.Import):
                tops = {a.name.split(".")[0] for a in node.names}
            elif isinstance(node, ast.ImportFrom):
                tops = {(node.module or "").split(".")[0]} if node.level == 0 else {"<relative>"}
            else:
                continue
            assert not tops & (names | {"experiments", "<relative>"}), (path.name, tops)


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


def test_online_table_rows_are_configurations_of_today_s_code():
    """Every row is an OnlineConfig (no dropped option), with the rules before round 8 unless it
    names its own; round5 and heldout (the README's table) are there."""
    from cosim.online.config import OnlineConfig

    table = _script("online_table")
    assert {"round5", "heldout"} <= set(table.TABLES)
    for name, (_title, seeds, budget, rows) in table.TABLES.items():
        assert table.seed_range(seeds) and budget > 0, name
        for label, options in rows:
            config = OnlineConfig(**{**table.BEFORE_ROUND8, **options})
            assert config.loop_blame == "leg" and config.fail_rates is False, (name, label)
    assert table.seed_range("1-3,7") == [1, 2, 3, 7]


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


def test_link_bytes_tabulates_a_run_and_its_configuration_is_valid():
    """The lifetime itself needs Verilator (docs/learner.md gives its figures); its table and its
    configuration are checked here."""
    from cosim.online.config import OnlineConfig

    link = _script("link_bytes")
    assert OnlineConfig(ga="hardware", **link.SHORT).n_targets == 2
    figures = {"ga": "hardware", "cpu_s": 70.3, "wall_s": 80.0, "loadavg": ["1.0", "1.0", "1.0"],
               "interactions": 315, "learning_phases": 49, "generations": 98, "targets": 2,
               "bytes_sent": 30, "bytes_received": 12, "requests": 3, "resends": 0,
               "by_command": {"LEARN": [11, 25], "MOTION": [19, 2]}}
    lines = link.table(figures).splitlines()
    assert lines[0].startswith("`--ga hardware`: 315 interactions, 49 phases, 98 generations, 2 targets")
    assert lines[4:] == ["| LEARN | 11 | 25 |", "| MOTION | 19 | 2 |",
                         "| **all** (3 requests, 0 resends) | **30** | **12** |"]

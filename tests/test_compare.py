"""cosim.compare: the comparison table, the ratio, and the fixed controller under a blinded sensor."""

from __future__ import annotations

import json

import numpy as np

from cosim.compare import build_report, fixed_controller_adaptation, main, markdown
from ga.genome import hex_from_rows
from ga.operators import random_population


def _fake(interactions, generations, pop):
    return {"interactions": interactions, "generations": generations,
            "genetic_operations": generations * pop, "world_states": 100, "transitions": 300,
            "targets_reached": 64}


def test_report_medians_ranges_and_ratio():
    results = {
        "online": {1: _fake(10_000, 400, 500), 2: _fake(12_000, 500, 500), 3: _fake(20_000, 600, 500)},
        "offline": {1: _fake(3_000_000, 300, 20), 2: _fake(2_400_000, 250, 20), 3: _fake(4_000_000, 280, 20)},
    }
    report = build_report(results, "default", [1, 2, 3])
    on = report["methods"]["online"]["interactions"]
    assert on == {"median": 12_000.0, "min": 10_000, "max": 20_000}
    assert report["interaction_ratio"]["of_medians"] == 3_000_000 / 12_000
    assert report["interaction_ratio"]["per_seed"] == [300.0, 200.0, 200.0]
    text = markdown(report)
    assert "| interactions | 12,000 (10,000-20,000) | 3,000,000 (2,400,000-4,000,000) | 12,280 | 3,283,269 |" in text
    assert "**250**" in text


def test_fixed_controller_under_a_blinded_sensor_is_counted():
    genome = hex_from_rows(random_population(np.random.default_rng(0), 1)[0])
    res = fixed_controller_adaptation(genome, "empty", seed=1, bit=0, after=3, window=2, max_leg_steps=50)
    assert res["targets"] <= 2 and res["interactions"] <= 2 * 50
    if res["targets"] < 2:
        assert res["interactions_for_next_targets"] is None


def test_command_line_baseline_only(tmp_path):
    assert main(["--seeds", "1", "--jobs", "1", "--methods", "baseline", "--out", str(tmp_path)]) == 0
    report = json.loads((tmp_path / "compare.json").read_text())
    assert report["per_seed"]["baseline"]["1"]["interactions"] > 0
    assert "reactive baseline" in (tmp_path / "compare.md").read_text()


def test_online_options_are_typed_checked_and_reported():
    import pytest

    from cosim.compare import online_options

    assert online_options(["distance_rule=covered", "loop_cycles=0", "escape=false"]) == \
        {"distance_rule": "covered", "loop_cycles": 0, "escape": False}
    with pytest.raises(ValueError, match="--distance"):
        online_options(["distance_rule=backward"])
    with pytest.raises(SystemExit, match="KEY=VALUE"):
        online_options(["no_such_field=1"])
    report = build_report({"online": {1: _fake(9_000, 300, 500)}}, "default", [1])
    report.update(online_distance_rule="covered", online_options={"distance_rule": "covered", "loop_cycles": 0})
    text = markdown(report)
    assert "first reading" in text and "`loop_cycles=0`" in text

"""The learning board (cosim.boards.LearningBoard): reference and Amaranth backends agree, and the
on-line run's --ga hardware option."""

import pytest

from cosim.online import OnlineConfig, make_run
from cosim.online_cli import main


def test_online_hardware_ga_reference_equals_amaranth():
    """Two phases of --ga hardware on both backends (the Amaranth learning board also checks
    every learn against its own reference: cosim.amaranth_learning)."""
    config = OnlineConfig(seed=2, ga="hardware", population=6, tournament=2, lanes=2,
                          generations_per_phase=2)
    runs = [make_run(config, b).run(stop_after_phases=2) for b in ("reference", "amaranth")]
    keys = ("reason", "interactions", "best_fitness", "best_crashes", "best_loops", "best_distance",
            "new_motion", "engine_cycles")
    assert [[p[k] for k in keys] for p in runs[0].phases] == [[p[k] for k in keys] for p in runs[1].phases]
    assert runs[0].motions == runs[1].motions and len(runs[0].phases) == 2
    assert runs[0].generations == 4 and runs[0].genetic_operations == 24


def test_online_hardware_ga_learns():
    run = make_run(OnlineConfig(seed=5, ga="hardware"), "reference")  # population 500, 8 lanes
    run.run(stop_after_phases=15)
    assert run.targets >= 3 and all("engine_cycles" in p for p in run.phases)
    assert any(p.get("escaped") for p in run.phases)


def test_hardware_ga_option_checks(capsys):
    with pytest.raises(ValueError, match="--ga must be"):
        OnlineConfig(ga="gpu")
    with pytest.raises(ValueError, match="--lanes must be"):
        OnlineConfig(ga="hardware", lanes=0)
    assert main(["--ga", "hardware", "--backend", "cocotb", "--out", "/nonexistent"]) == 2
    assert capsys.readouterr().err.startswith("error: --ga hardware runs on")

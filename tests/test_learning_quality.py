"""benchmarks.learning_quality's report: medians, their ratio and the per-seed pairing (no lifetimes run)."""

import json

import pytest

from benchmarks.learning_quality import main, report


def _row(seed, ga, interactions, targets=64):
    return {"seed": seed, "ga": ga, "targets": targets, "interactions": interactions}


def test_report_pairs_the_seeds():
    rows = [_row(1, "host", 1000), _row(1, "hardware", 2000), _row(2, "host", 4000), _row(2, "hardware", 2000),
            _row(3, "host", 3000, targets=60)]
    out = report(rows)
    assert out["host"] == {"runs": 3, "reached_64": 2, "median_interactions": 3000}
    assert out["hardware"]["median_interactions"] == 2000 and out["ratio_hardware_to_host"] == round(2000 / 3000, 3)
    # seed 3 has no hardware lifetime: two pairs, one shorter, ratios 2 and 0.5 -> geometric mean 1
    assert (out["paired_seeds"], out["hardware_shorter"], out["geometric_mean_ratio"]) == (2, 1, 1.0)
    assert "paired_seeds" not in report([_row(1, "host", 1000)])


def test_finished_seeds_are_not_run_again(tmp_path, capsys):
    out = tmp_path / "q.jsonl"
    out.write_text("".join(json.dumps(r) + "\n" for r in (_row(5, "host", 900), _row(5, "hardware", 1800))))
    assert main(["--seeds", "5", "--out", str(out)]) == 0  # both lifetimes of seed 5 are in the file
    assert out.read_text().count("\n") == 2
    assert json.loads(capsys.readouterr().out)["ratio_hardware_to_host"] == 2.0
    with pytest.raises(SystemExit):
        main(["--seeds", "9-3", "--out", str(out)])
    assert "error: argument --seeds: expected FIRST-LAST or one seed, got '9-3'" in capsys.readouterr().err



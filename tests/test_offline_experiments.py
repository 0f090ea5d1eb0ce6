"""experiments/offline_transfer_failures.py: the diagnosis of a controller's noisy-world runs."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np

from ga.genome import hex_from_rows

SCRIPT = Path(__file__).resolve().parent.parent / "experiments" / "offline_transfer_failures.py"


def test_diagnosis_names_the_failing_step():
    spec = importlib.util.spec_from_file_location("offline_transfer_failures", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    # An empty controller: forward wherever the reflex does not decide -> into the first obstacle.
    rows = module.diagnose(hex_from_rows(np.zeros(50, dtype=np.uint32)), "default", 150, trials=2,
                           first_seed=5)
    assert [r["seed"] for r in rows] == [5, 6]
    for r in rows:
        assert r["kind"] in ("crash", "time-out") and r["targets"] < 64
        if r["kind"] == "crash":
            assert 0 <= r["state"] < 256 and r["motion"] in range(8) and r["clearance_mm"] >= 0

"""Round 15 of the on-line search (docs/online.md, "Round 15"): the failure rates' parameters, now
that they are the default (``ga.fail_rates``, ``OnlineConfig.fail_rates``).

    python experiments/online_round15.py VARIANT SEEDS [--budget 20000] [--set key=value ...]
                                         [--param key=value ...]
    python experiments/online_round15.py default 1-16                      # = ehw sim --no-rate-mirror
    python experiments/online_round15.py rates 1-16 --param w=2            # F weighs twice
    python experiments/online_round15.py rates 1-16 --param horizon=12 --param prior=12
    python experiments/online_round15.py --table build/experiments/round15.jsonl

A lifetime is round 14's (``experiments.online_round14.Round14``: its ``thrash`` and ``downloads``
instruments) on the main code's defaults, failure rates on (``--set fail_rates=false`` for SPEC
section 7's fitness; rounds 8-14's scripts keep them off; round 16's mirror pooling is off here,
``OnlineConfig.rate_mirror``). Variant ``rates``, host side only:

- ``w``: the host fitness takes ``w`` x F (``w`` = 2: a pair that always fails weighs two crashes;
  on the learning engine that would be a shift of F);
- ``horizon``: the steps before a failure whose pairs it marks (the main code's ``HORIZON``, 8);
- ``prior``: the code of a pair never executed (``PRIOR_CODE``, 25 = rate 0.1; the host then
  writes every code that differs from the board's cleared 25 at the first phase).
"""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments.online_round8 import main as round8_main  # noqa: E402
from experiments.online_round14 import DEFAULT_PARAMS as R14_PARAMS  # noqa: E402
from experiments.online_round14 import Round14  # noqa: E402
from experiments.online_round14 import table as round14_table  # noqa: E402
from ga.fail_rates import HORIZON, PRIOR_CODE, RATE_ONE, FailureMarks  # noqa: E402

DEFAULT_OUT = Path("build/experiments/round15.jsonl")
VARIANTS = ("default", "rates")
R15_PARAMS = {"w": 1.0, "rate_horizon": HORIZON, "prior_code": PRIOR_CODE}
DEFAULT_PARAMS = {**R14_PARAMS, **R15_PARAMS}


class Marks(FailureMarks):
    """The main code's marks with another prior code."""

    def __init__(self, horizon: int, prior_code: int):
        super().__init__(horizon)
        self.prior_code = int(prior_code)

    def codes(self) -> np.ndarray:
        den = self.executed + 1
        return ((2 * (RATE_ONE * self.failed + self.prior_code) + den) // (2 * den)).astype(np.uint8)


class Weighted:
    """An evaluator board whose ``field`` counts (fails, or another of ``EvalResult``'s) are
    multiplied by ``w`` (the host fitness's weight)."""

    def __init__(self, board, w: float, field: str = "fails"):
        self._board, self._w, self._field = board, w, field

    def __getattr__(self, name):
        return getattr(self._board, name)

    def evaluate(self, population):
        counts = self._board.evaluate(population)
        return dataclasses.replace(counts, **{self._field: np.asarray(getattr(counts, self._field)) * self._w})


class Round15(Round14):
    """Round 14's lifetime (variant ``default``: the main code's failure rates) with ``rates``."""

    fail_rates = True  # the main code's default since this round

    def __init__(self, *a, **k):
        super().__init__(*a, **k)
        if self.variant == "rates" and self.config.fail_rates:
            prm = self.params
            self.marks = Marks(int(prm["rate_horizon"]), int(prm["prior_code"]))
            if float(prm["w"]) != 1.0:
                self.evaluator = Weighted(self.evaluator, float(prm["w"]))


def main(argv=None) -> int:
    return round8_main(argv, cls=Round15, defaults=DEFAULT_PARAMS, variants=VARIANTS, default_out=DEFAULT_OUT,
                       description=__doc__, table_of=round14_table)


if __name__ == "__main__":
    raise SystemExit(main())

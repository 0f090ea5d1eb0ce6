"""The on-line GA's and detectors' values before issue 36's tuning (``cosim/online/config.py``
names them). The short lifetimes that compare backends pin them: with them a few generations show
crash, loop and time-out phases; under the tuned values the same lifetimes take 5-10x more
generations (seed 21's 7 phases become 84) and no time-out."""

PRE_TUNING = dict(generations_per_phase=10, literal_rate=0.004, output_rate=0.004, switch_rate=0.01,
                  replace_rate=0.005, max_leg_steps=500, loop_window=100, progress_weight=3.0)


def pre_tuning(**options) -> dict:
    """``options`` over :data:`PRE_TUNING` (the options win)."""
    return {**PRE_TUNING, **options}

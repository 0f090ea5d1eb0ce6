"""The off-line method's robust stage (issue 17): deterministic perturbed worlds after the noise-free
evolution.

The noise-free GA of `cosim.offline` stops when its best controller reaches the 64 targets; that
controller follows walls and grazes obstacles so closely that the motor noise of the "real" world
makes it crash: its heading drifts along a wall, and a step that passes 34-43 mm from an obstacle
noise-free hits it with a longer step or a turned heading (docs/offline.md, rounds 2 and 3).
Selecting on noisy runs was too noisy for a population of 20 (round 3). With a robust stage
(``bias_deg`` not empty) the same GA goes on once the noise-free best reaches every target, and
from then on every individual drives a few *scenarios*: noise-free worlds with a systematic motor
error (`sim_world.world.Bias`), docs/offline.md round 4:

- the heading of every motion turned by +b degrees in one scenario and by -b in the other (drift
  towards either side accumulates along a wall, as the noise's random walk does, but every
  individual meets the same drift), each with every translation scaled by 1 + x for each x of
  ``translations`` (a longer step exposes a near miss, a shorter one a leg that only just
  finishes in time): 2 x len(translations) scenarios; with ``paired`` one per x, the sign
  alternating ((0.1, -0.1): +b with long steps, -b with short ones);
- the fitness is SPEC section 7's, summed over the scenarios (``combine="sum"``) or their minimum
  (``"min"``: the scenarios stay balanced); a run stops at its first crash or leg time-out, as
  noise-free;
- every run is deterministic, so there is no selection noise: the elite's fitness never falls
  within a level, and "reaches 64 in every scenario" is a plain test. When the best does, the
  stage moves to the next bias of ``bias_deg`` (a schedule: 2, 3, 4 degrees); after the last one
  the run ends. Otherwise it ends after ``max_generations`` of the stage or once the whole run
  has spent ``budget`` interactions (or ``budget_factor`` times those of its noise-free stage),
  and the result is the elite that passed the last level passed, or the noise-free best if no
  level was passed (an elite of the level under way may be better there and worse elsewhere).

Every motion of every scenario is an interaction of the off-line method (issue 17's rule).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

from sim_world.world import Bias

COMBINES = ("sum", "min")


@dataclass(frozen=True)
class RobustStage:
    """Parameters of the robust stage; an empty ``bias_deg`` means none (the paper's method)."""

    bias_deg: tuple[float, ...] = ()  # heading bias (degrees a motion) of each level, in order
    translations: tuple[float, ...] = (0.0,)  # step scale 1 + x of the scenarios, for each x
    paired: bool = False  # one world per step scale, the bias sign alternating (+b, -b, +b, ...)
    combine: str = "sum"  # the fitness over the scenarios: their sum or their minimum
    max_generations: int = 1000  # the stage's cap
    budget: int = 0  # the whole run's interactions: the stage ends once they reach it (0: no limit)
    budget_factor: float = 0.0  # ... or once they reach this many times the noise-free stage's (0: none)

    def __post_init__(self):
        object.__setattr__(self, "bias_deg", tuple(float(b) for b in self.bias_deg))
        object.__setattr__(self, "translations", tuple(float(x) for x in self.translations))
        for b in self.bias_deg:
            if not 0 < b < 45:
                raise ValueError(f"bias_deg: every bias must be in (0, 45) degrees, got {b!r}")
        if not self.translations or not all(-0.5 < x < 0.5 for x in self.translations):
            raise ValueError(f"translations: one or more, each in (-0.5, 0.5), got {self.translations!r}")
        if self.combine not in COMBINES:
            raise ValueError(f"combine must be one of {COMBINES}, got {self.combine!r}")
        for name, least in (("max_generations", 1), ("budget", 0)):
            value = getattr(self, name)
            if not (isinstance(value, int) and value >= least):
                raise ValueError(f"{name} must be an int >= {least}, got {value!r}")
        if not (math.isfinite(self.budget_factor) and (self.budget_factor == 0 or self.budget_factor >= 1)):
            raise ValueError(f"budget_factor must be 0 (none) or >= 1, got {self.budget_factor!r}")

    @property
    def enabled(self) -> bool:
        return bool(self.bias_deg)

    @property
    def levels(self) -> int:
        return len(self.bias_deg)

    def scenarios(self, level: int) -> tuple[Bias, ...]:
        """The worlds of ``level``: heading bias +b and -b for each step scale (``paired``: one
        world per step scale, the sign alternating)."""
        b = self.bias_deg[level]
        if self.paired:
            return tuple(Bias(rotation_deg=(-b if k % 2 else b), translation_scale=1.0 + x)
                         for k, x in enumerate(self.translations))
        return tuple(Bias(rotation_deg=sign * b, translation_scale=1.0 + x)
                     for x in self.translations for sign in (1.0, -1.0))

    def combined(self, fitnesses) -> float:
        """One individual's fitness from its scenarios' fitnesses."""
        return float(sum(fitnesses) if self.combine == "sum" else min(fitnesses))

    def to_dict(self) -> dict:
        d = asdict(self)
        d["bias_deg"] = list(self.bias_deg)
        d["translations"] = list(self.translations)
        return d

"""The off-line method's robust stage (issue 17): deterministic perturbed worlds after the noise-free
evolution.

The noise-free GA of `cosim.offline` stops when its best controller reaches the 64 targets; that
controller follows walls and grazes obstacles so closely that the motor noise of the "real" world
makes it crash: its heading drifts along a wall, and a step that passes 34-43 mm from an obstacle
noise-free hits it with a longer step or a turned heading (docs/offline.md, rounds 2 and 3).
Selecting on noisy runs was too noisy for a population of 20 (round 3). With a robust stage
(``bias_deg`` not empty) the same GA goes on once the noise-free best reaches every target, and
from then on every individual drives a few *scenarios*: noise-free worlds with a systematic motor
error (`sim_world.world.Bias`):

- the heading of every motion turned by +b degrees in one scenario and by -b in the other (drift
  towards either side accumulates along a wall, as the noise's random walk does, but every
  individual meets the same drift), each with every translation scaled by 1 + x for each x of
  ``translations`` (a longer step exposes a near miss, a shorter one a slow leg): 2 x
  len(translations) scenarios (with ``paired``, one per x, the sign alternating: (0.1, -0.1)
  gives +b with long steps and -b with short ones), plus the unperturbed world if ``noise_free`` (a loop there that the
  perturbations break is a loop the real robot may meet too);
- the fitness is SPEC section 7's, summed over the scenarios (``combine="sum"``) or their minimum
  (``"min"``); a run stops at its first crash or leg time-out, as noise-free;
- every run is deterministic, so there is no selection noise: the elite's fitness never falls,
  and "reaches 64 in every scenario" is a plain test. When the best does, the stage moves to the
  next bias of ``bias_deg`` (a schedule: 1, 2, ... degrees); after the last one the run ends.
  Otherwise it ends after ``max_generations`` of the stage or once the whole run has spent
  ``budget`` interactions (or ``budget_factor`` times those of its noise-free stage), and the
  result is the elite that passed the last level passed (an elite of the level under way may
  be better there and worse elsewhere), or the elite if no level was passed.
- ``max_failures`` > 0: a graded run, a crash or a time-out fails only its leg and the run goes on
  at the next leg's pose (up to that many failed legs); R1 counts the clean legs. In a
  deterministic world every leg is then a test of its own, so the GA can mend several hard legs
  at once instead of waiting at the first one.
- ``max_leg_steps`` below the run's leg limit asks the perturbed runs to finish each leg with
  slack: the noise makes legs slower, and a leg that needs 140 steps noise-free times out at 150.
- ``validate_runs`` > 0: every ``validate_every`` generations and at each level passed, the elite
  (if not validated before) drives ``validate_runs`` noisy runs on fixed validation seeds, every
  leg tried; the run's result is the validated elite with the fewest failed legs. (The elites of
  a stage differ in how they fare in noise, and the last is not always the best.)

Every motion of every scenario is an interaction of the off-line method (issue 17's rule).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

from sim_world.world import Bias

COMBINES = ("sum", "min")
NOISE_TAG = 170_018  # first word of the frozen noise seeds (never a transfer or diagnosis seed)
VALIDATION_TAG = 170_019  # first word of the validation noise seeds


@dataclass(frozen=True)
class FrozenNoise:
    """A scenario in the noisy world (`sim_world.world.DEFAULT_NOISE`) whose noise is the same in
    every generation: leg j is re-seeded with ``[*seed, j]``, so a run is still a pure function of
    the controller (no selection noise), but it meets random drift, step errors and IR errors."""

    seed: tuple[int, ...]

    def leg_seed(self, leg: int) -> list[int]:
        return [*self.seed, int(leg)]


@dataclass(frozen=True)
class RobustStage:
    """Parameters of the robust stage; an empty ``bias_deg`` means none (the paper's method)."""

    bias_deg: tuple[float, ...] = ()  # heading bias (degrees a motion) of each level, in order
    translations: tuple[float, ...] = (0.0,)  # step scale 1 + x of the scenarios, for each x
    paired: bool = False  # one world per step scale, the bias sign alternating (+b, -b, +b, ...)
    noise_free: bool = False  # the unperturbed world is one more scenario
    frozen_noise: int = 0  # this many FrozenNoise scenarios more, the same at every level
    validate_runs: int = 0  # noisy validation runs of the elite (0: none; the last elite is the result)
    validate_every: int = 5  # generations between validations (and at every level passed)
    combine: str = "sum"  # the fitness over the scenarios: their sum or their minimum
    max_generations: int = 1000  # the stage's cap: then the elite is the result
    budget: int = 0  # the whole run's interactions: the stage ends once they reach it (0: no limit)
    budget_factor: float = 0.0  # ... or once they reach this many times the noise-free stage's (0: none)
    max_leg_steps: int = 0  # the leg limit in the scenarios (0: the run's)
    max_failures: int = 0  # graded runs: a failure ends its leg, up to this many (0: ends the run)

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
        for name, least in (("max_generations", 1), ("budget", 0), ("max_leg_steps", 0), ("frozen_noise", 0), ("validate_runs", 0), ("validate_every", 1),
                            ("max_failures", 0)):
            value = getattr(self, name)
            if not (isinstance(value, int) and value >= least):
                raise ValueError(f"{name} must be an int >= {least}, got {value!r}")
        if not (self.budget_factor == 0 or self.budget_factor >= 1):
            raise ValueError(f"budget_factor must be 0 (none) or >= 1, got {self.budget_factor!r}")

    @property
    def enabled(self) -> bool:
        return bool(self.bias_deg)

    @property
    def levels(self) -> int:
        return len(self.bias_deg)

    def scenarios(self, level: int, seed: int = 0) -> tuple[Bias | FrozenNoise | None, ...]:
        """The worlds of ``level``: heading bias +b and -b for each step scale, then None (the
        unperturbed world) if ``noise_free``, then the run ``seed``'s frozen noise scenarios."""
        b = self.bias_deg[level]
        if self.paired:
            worlds = tuple(Bias(rotation_deg=(-b if k % 2 else b), translation_scale=1.0 + x)
                           for k, x in enumerate(self.translations))
        else:
            worlds = tuple(Bias(rotation_deg=sign * b, translation_scale=1.0 + x)
                           for x in self.translations for sign in (1.0, -1.0))
        frozen = tuple(FrozenNoise((NOISE_TAG, int(seed), k)) for k in range(self.frozen_noise))
        return worlds + ((None,) if self.noise_free else ()) + frozen

    def validation_seeds(self, seed: int) -> list[tuple[int, int, int]]:
        """The noise seeds of the validation runs (the same for every elite of run ``seed``)."""
        return [(VALIDATION_TAG, int(seed), k) for k in range(self.validate_runs)]

    def combined(self, fitnesses) -> float:
        """One individual's fitness from its scenarios' fitnesses."""
        return float(sum(fitnesses) if self.combine == "sum" else min(fitnesses))

    def to_dict(self) -> dict:
        d = asdict(self)
        d["bias_deg"] = list(self.bias_deg)
        d["translations"] = list(self.translations)
        return d

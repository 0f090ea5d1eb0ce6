"""The configuration of one on-line lifetime (``cosim.online.run``): every field checked at once.

An invalid value is a ``ValueError`` whose message names the command-line option of the field
(``cosim.cli.online``), e.g. ``--loop-window must be >= 0, got -3``.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from cosim.online.failures import Cycles, LegTimeout, NoProgress, Reentries, Repeats
from ga.evolution import GAConfig
from ga.hardware_ga import LEARNER_LANES
from ga.motions import DISTANCE_RULES
from sim_world.world import CAMERA_RANGE_SD, DEFAULT_NOISE, Noise

# The seeds the on-line defaults were chosen on: every round of docs/research-log.md chose (or
# screened, or confirmed a choice) on seeds below 281; from 281 on none chose anything (281-300 is
# round 18's held-out set; honest sensing's cycle rule was chosen on 1-15); `ehw tune online` chose
# the GA's and the detectors' values on 1001-1005. `ehw compare` says whether the seeds it reports
# meet these.
CHOSEN_ON_SEEDS = tuple(range(1, 281)) + tuple(range(1001, 1006))

LOOP_BLAMES = ("cycle", "leg")  # OnlineConfig.loop_blame (docs/research-log.md, on-line round 8)

# The command-line option of each OnlineConfig field (cosim.cli.online), named in error messages.
OPTIONS = {"n_targets": "--targets", "distance_rule": "--distance"}


def option(field: str) -> str:
    return OPTIONS.get(field, "--" + field.replace("_", "-"))


@dataclass(frozen=True)
class OnlineConfig:
    """Everything that defines one on-line run (a checkpoint resumes only under the same config)."""

    seed: int = 1
    arena: str = "default"
    n_targets: int = 64
    noise: bool = True  # the "real" world: sim_world.world.DEFAULT_NOISE
    # the camera's range estimate in that world, r = true (1 + e), e ~ N(0, range_noise) (SPEC
    # section 4): all the host learns progress towards the ball from (not the exact distance)
    range_noise: float = CAMERA_RANGE_SD
    reflex: bool = True
    # GA (SPEC section 7: population 500, tournament 20, elitism, about 10 generations a phase)
    population: int = 500
    tournament: int = 20
    elitism: int = 1
    # the GA's rates, its generations a phase, the two detectors' limits and progress_weight below:
    # `ehw tune online` (20 trials on seeds 1001-1005, TPE seed 0; docs/peers.md), median 4,303 there
    # against 4,879 with the earlier values (10, 0.004, 0.004, 0.01, 0.005; 500, 100; 3.0)
    generations_per_phase: int = 8
    crossover_rate: float = 0.5
    literal_rate: float = 0.0018453118363595822
    output_rate: float = 0.005123044866651734
    switch_rate: float = 0.0037361640743266106
    replace_rate: float = 0.001676303427594598
    # execution phase: the failure detectors (cosim.online.failures); 0 switches one off
    max_leg_steps: int = 230  # leg time-out: steps on one leg since the phase began
    loop_window: int = 174  # no new closest approach to the ball for this many steps
    loop_reentries: int = 4  # entries into one obstacle state (round 3, docs/online.md)
    loop_repeats: int = 4  # repetitions of one cycle of 2..6 (state, motion) pairs (round 3)
    loop_radius_mm: float = 80.0  # the two above and loop_cycles: back within this, by odometry
    loop_cycles: int = 1  # rounds of one simple state cycle (SPEC section 7; round 5)
    # False (the default since honest sensing, docs/online.md): the cycle stop by odometry alone, any
    # rounds within loop_radius_mm; True: only rounds since the last new closest approach to the ball
    # by the camera's range (before issue 36, by the exact distance)
    cycles_after_approach: bool = False
    # dist[a] of the fitness (ga.motions.DISTANCE_RULES): "forward" is SPEC section 7 (backward
    # motions cover 0; round 5); "covered", every translation, is the paper's first reading
    distance_rule: str = "forward"
    # learning phase: after a time-out or loop, download the fittest individual whose motion in the
    # blamed state differs from the failed one (cosim.online.download; docs/research-log.md, on-line round 1)
    escape: bool = True
    # the (state, motion) a cycle stop is blamed on (cosim.online.failures): "cycle", a pair of the cycle
    # that stopped the leg (round 8), or "leg", the leg's most frequent obstacle pair (rounds 1-7)
    loop_blame: str = "cycle"
    # the robot's own failure rates per (state, motion) as a fourth fitness term (ga.fail_rates;
    # docs/research-log.md, on-line rounds 14-15: the default since round 15); False: SPEC section 7's three terms
    fail_rates: bool = True
    # the rate codes pool each pair's counts with its left-right mirror image's (ga.fail_rates;
    # docs/research-log.md, on-line round 16); False: each pair's own counts (round 15)
    rate_mirror: bool = True
    # each rate code also carries the pair's progress deficit, its mean gain towards the ball over
    # the next 8 steps against the best of its state's (ga.fail_rates.progress_codes; docs/online.md,
    # round 18: the default since then), with this weight; 0: none (and none without fail_rates)
    progress_weight: float = 0.591151182060115
    max_interactions: int = 100_000  # end the lifetime there even short of n_targets (0: no limit)
    # The GA of the learning phases: "host" (ga.evolution on the host, the evaluator board
    # evaluates) or "hardware" (the learning board: ga.hardware_ga / hdl.learner with `lanes`
    # evaluator lanes, SPEC section 12; cosim.online.learning_phase, docs/learner.md)
    ga: str = "host"
    lanes: int = LEARNER_LANES  # the ulx3s-learner bitstream's (ga.hardware_ga)
    # adaptation: blind IR bit `blind_bit` (stuck at 0) once `blind_after_target` targets are reached
    blind_bit: int | None = None
    blind_after_target: int | None = None

    def __post_init__(self):
        def check(ok: bool, field: str, what: str):
            if not ok:
                raise ValueError(f"{option(field)} must be {what}, got {getattr(self, field)!r}")

        for field in ("seed", "n_targets", "population", "tournament", "elitism", "generations_per_phase",
                      "max_leg_steps", "loop_window", "loop_reentries", "loop_repeats", "loop_cycles",
                      "max_interactions"):
            value = getattr(self, field)
            check(isinstance(value, (int, np.integer)) and not isinstance(value, bool), field, "an integer")
        for field in ("n_targets", "population", "tournament", "generations_per_phase", "max_leg_steps"):
            check(getattr(self, field) >= 1, field, ">= 1")
        for field in ("seed", "loop_window", "loop_reentries", "loop_repeats", "loop_cycles", "max_interactions"):
            check(getattr(self, field) >= 0, field, ">= 0")
        check(0 <= self.elitism <= self.population, "elitism", "in 0..population")
        for field in ("crossover_rate", "literal_rate", "output_rate", "switch_rate", "replace_rate"):
            value = getattr(self, field)
            check(isinstance(value, (int, float)) and 0.0 <= value <= 1.0, field, "a rate in [0, 1]")
        value = self.loop_radius_mm
        check(isinstance(value, (int, float)) and math.isfinite(value) and value >= 0, "loop_radius_mm",
              "a finite distance >= 0")
        value = self.range_noise
        check(isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
              and value >= 0, "range_noise", "a finite relative error >= 0")
        value = self.progress_weight
        check(isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
              and value >= 0, "progress_weight", "a finite weight >= 0")
        if not self.fail_rates:  # the deficit rides on the rate codes: none without them
            object.__setattr__(self, "progress_weight", 0.0)
        check(self.distance_rule in DISTANCE_RULES, "distance_rule", f"one of {', '.join(DISTANCE_RULES)}")
        for field in ("noise", "reflex", "escape", "fail_rates", "rate_mirror", "cycles_after_approach"):
            check(isinstance(getattr(self, field), bool), field, "True or False")
        check(isinstance(self.arena, str) and bool(self.arena), "arena", "an arena name or .json path")
        check(self.ga in ("host", "hardware"), "ga", "host or hardware")
        check(self.loop_blame in LOOP_BLAMES, "loop_blame", f"one of {', '.join(LOOP_BLAMES)}")
        check(isinstance(self.lanes, int) and not isinstance(self.lanes, bool) and 1 <= self.lanes <= 48,
              "lanes", "an integer in 1..48")
        if (self.blind_bit is None) != (self.blind_after_target is None):
            raise ValueError("--blind-bit and --blind-after-target go together, got "
                             f"{self.blind_bit!r} and {self.blind_after_target!r}")
        if self.blind_bit is not None:
            check(self.blind_bit in range(6), "blind_bit", "an IR bit 0..5")
            check(isinstance(self.blind_after_target, int) and self.blind_after_target >= 1,
                  "blind_after_target", "a target >= 1")
            if self.blind_after_target >= self.n_targets:  # the lifetime ends there: no blinding at all
                raise ValueError(f"--blind-bit {self.blind_bit!r} --blind-after-target {self.blind_after_target!r}: "
                                 f"the lifetime has {self.n_targets} targets, so the bit would never be "
                                 f"blinded; choose a target in 1..{self.n_targets - 1}")

    def world_noise(self) -> Noise | None:
        """The world's noise: DEFAULT_NOISE with the camera's ``range_noise``; None without ``noise``."""
        return dataclasses.replace(DEFAULT_NOISE, range_sd=float(self.range_noise)) if self.noise else None

    def ga_config(self) -> GAConfig:
        return GAConfig(
            population=self.population, tournament=self.tournament, elitism=self.elitism,
            crossover_rate=self.crossover_rate, literal_rate=self.literal_rate,
            output_rate=self.output_rate, switch_rate=self.switch_rate, replace_rate=self.replace_rate,
        )

    def detectors(self) -> list:
        """The failure detectors of the execution phase, in the order they are checked."""
        found = [LegTimeout(self.max_leg_steps)]
        if self.loop_window:
            found.append(NoProgress(self.loop_window))
        if self.loop_reentries:
            found.append(Reentries(self.loop_reentries, self.loop_radius_mm))
        if self.loop_repeats:
            found.append(Repeats(self.loop_repeats, self.loop_radius_mm))
        if self.loop_cycles:
            found.append(Cycles(self.loop_cycles, self.loop_radius_mm, self.cycles_after_approach))
        return found

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)

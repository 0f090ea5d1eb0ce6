"""The on-line model-based experiment (paper section 5.2, SPEC section 7): one robot lifetime.

    python -m cosim.online --backend reference --seed 1 [--arena default] [--resume]
                           [--out results/model_based] [--continue-past-64 N]
                           [--blind-bit B --blind-after-target T]

Structure (an alternation of execution and learning phases, in sequence as in the paper):

- **Execution phase.** The controller board drives the robot in the noisy world (``DEFAULT_NOISE``):
  per step, ``a = controller.motion(s)``, one ``World.step(a)`` (one *interaction*), and
  ``evaluator.observe(s, a, s2, crashed)`` updates the world model on the evaluator board. Reaching
  the target relocates the robot to the next of the 64 poses. The phase ends on a *failure*: a
  crash, a leg time-out (``max_leg_steps`` steps on one leg since the phase began), or a
  real-world loop: no new closest approach to the ball for ``loop_window`` steps, or (since
  round 3, docs/online.md) an oscillation in place: ``loop_repeats`` repetitions of one short
  cycle of (state, motion) pairs, or ``loop_reentries`` entries into one obstacle state, each
  counted only while the robot is back within ``loop_radius_mm`` of where it was, by odometry
  (the commanded motions dead-reckoned), without a new closest approach meanwhile.
- **Learning phase.** ``generations_per_phase`` generations of the GA (population 500, tournament
  20, elitism; the GA is kept across phases), each population evaluated by
  ``evaluator.evaluate(pop)`` and scored with the normative fitness (``ga.evaluator.fitness``); the
  best is downloaded with ``controller.load(best)``. Optionally (``targeted``) part of the
  population is first rewritten at the state that failed (``ga.online_operators``).
- At the very start the model is empty and a random individual of the initial population drives.
- Stop at ``n_targets`` targets (64; more with ``--continue-past-64``).

The loop calls the boards only through ``cosim.boards`` (``load``, ``set_reflex``, ``motion``,
``observe``, ``evaluate``, ``cycles``); it is synchronous and keeps no global state, so an HDL
backend (or a cocotb test running it in a thread) plugs in unchanged.

Checkpoint and resume: after every learning phase the GA state, the counters, the phase records and
the log of executed motions go to ``<out>/checkpoint.json``. ``--resume`` rebuilds the world and
the evaluator board by replaying the logged motions (the world is deterministic for its seed), so a
resumed run is the uninterrupted run, bit for bit.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
import time
from collections import Counter, deque
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cosim.boards import BACKENDS, make_boards
from cosim.checkpoint import CheckpointError, load_checkpoint, save_checkpoint
from ga.evaluator import fitness as model_fitness
from ga.evolution import GAConfig, GeneticAlgorithm
from ga.genome import hex_from_rows, rows_from_hex
from ga.motions import DISTANCE_RULES, MOTION_ROTATION_DEG, MOTION_TRANSLATION_MM, OBSTACLE_MASK
from ga.online_operators import diversity, targeted_mutants
from ga.truth_table import truth_tables
from ga.world_model import WorldModel
from sim_world.world import DEFAULT_NOISE, Fault, World

CHECKPOINT_KIND = "online"
N_POSITIONS = 64
# The paper's figures (section 5.2) printed beside ours.
PAPER = {
    "interactions": 12_280,
    "generations": 485,  # 242,500 genetic operations / 500 individuals
    "genetic_operations": 242_500,
    "world_states": 84,
    "transitions": 334,
    "targets_reached": 64,
}


@dataclass(frozen=True)
class OnlineConfig:
    """Everything that defines one on-line run (a checkpoint resumes only under the same config)."""

    seed: int = 1
    arena: str = "default"
    n_targets: int = 64
    noise: bool = True  # the "real" world: sim_world.world.DEFAULT_NOISE
    reflex: bool = True
    # GA (SPEC section 7: population 500, tournament 20, elitism, about 10 generations a phase)
    population: int = 500
    tournament: int = 20
    elitism: int = 1
    generations_per_phase: int = 10
    crossover_rate: float = 0.5
    literal_rate: float = 0.004
    output_rate: float = 0.004
    switch_rate: float = 0.01
    replace_rate: float = 0.005
    # execution phase
    max_leg_steps: int = 500  # leg time-out: steps on one leg since the phase began
    loop_window: int = 100  # > 0: stop when no new closest approach to the ball for this many steps
    # > 0: stop when the robot has entered one obstacle state (from another state) this many times
    # since its last new closest approach to the ball (an oscillation, e.g. F/F -> F/L -> F/F)
    loop_reentries: int = 4  # default since round 3 (docs/online.md); 0: off
    # > 0: stop when the last (state, motion) pairs are this many repetitions of one cycle of
    # 2..6 pairs, without a new closest approach meanwhile (a periodic oscillation)
    loop_repeats: int = 4  # default since round 3 (docs/online.md); 0: off
    # the recent (state, motion) window that a time-out/loop is blamed on starts empty at each
    # execution phase (False: it also holds the previous phases' pairs, motions the controller
    # just downloaded may no longer choose)
    blame_phase_only: bool = False
    # what loop_repeats compares: "pair" = (state, motion); "motion" = the motion only (a cycle
    # whose states differ by a noisy IR bit is still caught)
    loop_key: str = "pair"
    # > 0: loop_repeats fires only if, besides, the ball distance one cycle apart differs by at
    # most this many mm (the cycle goes nowhere); 0: off
    loop_still_mm: float = 0.0
    # > 0: after this many loop stops on one leg (same target), loop_repeats and loop_reentries
    # are off until the next target (only loop_window and the time-out stop the leg): a detour
    # that must move away from the ball is not cut again and again; 0: off
    loop_patience: int = 0
    # > 0: after every this many loop stops on one leg (same target), the loop detectors relax one
    # level until the next target: loop_repeats and loop_reentries (and loop_window with
    # relax_window) are doubled per level (a detour that pays off only after a while is no longer
    # cut at once); 0: off
    loop_relax: int = 0
    # > 0: the loop detectors ask, besides, that the robot be back where it was, by odometry (the
    # commanded motions dead-reckoned, crashes not moving it): loop_reentries counts an entry
    # into a state only among the earlier entries (since the last new closest approach) within
    # this many mm, loop_repeats fires only if the repeated cycles moved the robot less than
    # this; a wall followed or a detour is not a loop. 0: off
    loop_radius_mm: float = 80.0  # default since round 3 (docs/online.md)
    # > 0: stop when the robot has gone this many times round one simple cycle of 2..8 states that
    # ends in the state it is in now (the last K p pairs repeat the p pairs that led from the
    # current state back to it), within loop_radius_mm by odometry and without a new closest
    # approach. Its transitions are then the world model's most recent entries, so the model
    # holds the loop the controller just ran (docs/online.md, round 5); 0: off
    loop_cycles: int = 0
    # the download among the individuals that tie for the best fitness (with escape: the best of
    # those that avoid the blamed motion): "first" = the first of them in the population;
    # "closest" = the one whose motions differ from the running controller's in the states the
    # robot has visited least often (the sum of the visits of every changed state): behaviour
    # the model cannot tell apart stays what worked in the world (docs/online.md, round 5)
    download: str = "first"
    # dist[a] of the model-based fitness (ga.motions.DISTANCE_RULES): "covered" is the SPEC (every
    # translation, backward too); "forward" (NOT the SPEC, an option) rewards forward translation
    # only. Measured in docs/online.md, round 5: the SPEC's reward for backing off is what keeps
    # the on-line robot looping.
    distance_rule: str = "covered"
    relax_window: bool = False
    # learning phase
    targeted: int = 0  # state-targeted mutants of the best written into the population per phase
    # after a time-out or loop, download the fittest individual whose motion in the blamed state
    # differs from the failed one (the model cannot see a real-world loop; see docs/online.md)
    escape: bool = True
    # with escape: avoid, in the blamed state, every motion blamed for an earlier time-out/loop
    # there (fewest blames first; motions the model knows to crash count as blamed), not only the
    # last one: stops the download flipping between two looping motions (docs/online.md)
    escape_memory: bool = False
    # with escape: after a time-out or loop, download, among the individuals no worse than the
    # fittest on the model's crashes and loops, the one that repeats the fewest obstacle
    # (state, motion) steps of the failed leg (ties: fitness): the blame is spread over every
    # obstacle pair of the leg, not put on one (docs/online.md, round 3). "leg": the steps of the
    # failing phase since its last target; "target": of every phase failed by a time-out or loop
    # since the last target; "off": the single blamed state (escape as above)
    escape_spread: str = "off"
    # > 0: after a time-out or loop, this many copies of the fittest individual get, in each of
    # the (up to 4) obstacle states the failed leg visited most often (at least twice), a motion
    # not yet executed there in a failed leg since the last target nor known to crash there
    # (ga.operators.set_state_motion); they are evaluated on the model (counted as genetic
    # operations) and the fittest of those no worse than the fittest individual on the model's
    # crashes and loops is downloaded and written into the population; 0: off
    escape_rewrite: int = 0
    # at every download (after crashes too), among the individuals no worse than the fittest on
    # the model's crashes and loops, the one whose motions in the model's obstacle states carry
    # the least blame (ties: fitness); the blame of (state, motion) = its steps in legs failed by
    # a time-out or loop minus its steps in legs that reached the target, over the lifetime (a
    # loop the model cannot hold is remembered here instead; docs/online.md, round 3)
    escape_credit: bool = False
    # NOT the normative fitness (SPEC section 7), an option: a controller loses loop_penalty / N of
    # fitness for each distinct obstacle (state, motion) blamed for a loop or time-out on the
    # current leg (since the last target) that it would choose again. The model cannot hold those
    # loops (docs/online.md), so without it the GA's selection soon brings the looping motion
    # back; the escape alone only changes one download. 0: off (the SPEC). Measured: docs/online.md.
    loop_penalty: float = 0.0
    # NOT the normative model update (SPEC section 7), an option: after a time-out or loop, the
    # blamed (state, motion) is written to the world model so that the fitness sees the real-world
    # loop: "self" = as a transition back to the same state (the fitness counts it as a loop; the
    # next real observation overwrites it), "crash" = as a crash (permanent). "off" = the SPEC.
    # See docs/online.md for the measurements.
    mark_loops: str = "off"
    mark_limit: int = 8  # no mark in a state that already has this many crash entries
    # The world-model update. "most_recent" is SPEC section 7 (normative, the default). The
    # option "most_frequent" (NOT the SPEC) writes to the evaluator the most often observed next
    # state of each (state, motion) (ties: the most recent), crash entries still permanent: one
    # noisy observation then no longer erases a loop seen fifty times (docs/online.md).
    model_update: str = "most_recent"
    max_interactions: int = 100_000  # end the lifetime there even short of n_targets (0: no limit)
    # adaptation: blind IR bit `blind_bit` (stuck at 0) once `blind_after_target` targets are reached
    blind_bit: int | None = None
    blind_after_target: int | None = None

    def __post_init__(self):
        if self.n_targets < 1:
            raise ValueError(f"n_targets must be at least 1, got {self.n_targets!r}")
        if self.max_leg_steps < 1:
            raise ValueError(f"max_leg_steps must be at least 1, got {self.max_leg_steps!r}")
        if self.generations_per_phase < 1:
            raise ValueError(f"generations_per_phase must be at least 1, got {self.generations_per_phase!r}")
        if self.escape_spread not in ("off", "leg", "target"):
            raise ValueError(f"escape_spread must be 'off', 'leg' or 'target', got {self.escape_spread!r}")
        if self.distance_rule not in DISTANCE_RULES:
            raise ValueError(f"distance_rule must be one of {DISTANCE_RULES}, got {self.distance_rule!r}")
        if self.download not in ("first", "closest"):
            raise ValueError(f"download must be 'first' or 'closest', got {self.download!r}")
        if self.loop_key not in ("pair", "motion"):
            raise ValueError(f"loop_key must be 'pair' or 'motion', got {self.loop_key!r}")
        if (self.blind_bit is None) != (self.blind_after_target is None):
            raise ValueError("blind_bit and blind_after_target go together, got "
                             f"{self.blind_bit!r} and {self.blind_after_target!r}")
        if self.blind_bit is not None and self.blind_bit not in range(6):
            raise ValueError(f"blind_bit must be an IR bit 0..5, got {self.blind_bit!r}")

    def ga_config(self) -> GAConfig:
        return GAConfig(
            population=self.population, tournament=self.tournament, elitism=self.elitism,
            crossover_rate=self.crossover_rate, literal_rate=self.literal_rate,
            output_rate=self.output_rate, switch_rate=self.switch_rate, replace_rate=self.replace_rate,
        )

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)


def _seeds(seed: int) -> tuple[int, np.random.Generator]:
    """The world's noise seed and the GA's generator, both derived from the run's seed."""
    world_seq, ga_seq = np.random.SeedSequence(seed).spawn(2)
    return int(world_seq.generate_state(1)[0]), np.random.default_rng(ga_seq)


class OnlineRun:
    """One robot lifetime of the on-line model-based method on a (controller, evaluator) board pair.

    ``run()`` goes to ``config.n_targets`` targets (or ``stop_after_phases`` learning phases);
    ``summary()`` gives the figures. Host-side bookkeeping (state set, transitions met, a mirror
    of the world model used only for instrumentation and targeted mutation) never feeds the
    boards: the evaluator board holds its own model, updated only by ``observe``.
    """

    def __init__(self, config: OnlineConfig, controller, evaluator, checkpoint: Path | None = None,
                 progress: bool = False, backend: str = "reference"):
        self.config = config
        self.controller = controller
        self.evaluator = evaluator
        self.checkpoint_path = checkpoint
        self.progress = progress
        self.backend = backend
        world_seed, self.rng = _seeds(config.seed)
        self.world = World(config.arena, noise=DEFAULT_NOISE if config.noise else None, seed=world_seed)
        self.ga = GeneticAlgorithm(config.ga_config(), self.rng)
        controller.set_reflex(config.reflex)
        # --- lifetime counters (rebuilt by replay on resume) ---
        self.motions: list[int] = []  # every motion executed, in order (the replay log)
        self.state_log: list[int] = []  # the state observed after each motion
        self.outcomes: dict[tuple[int, int], dict[int, int]] = {}  # (s, a) -> {s2: count}
        self.interactions = 0
        self.targets = 0
        self.leg_steps = 0  # steps on the current leg since the last (re)start of execution
        self.mirror = WorldModel()  # host copy of the model (instrumentation, targeted mutation)
        self.transitions: set[tuple[int, int, int, bool]] = set()
        self.trajectory: list[tuple[float, float, str]] = []
        self.curve_states: list[int] = []  # |S| after each interaction
        self.curve_transitions: list[int] = []
        self.known_crash_repeats = 0  # motions chosen in a state where the model knows they crash
        self.window = deque(maxlen=max(config.loop_window, 64))  # recent (state, motion)
        self.dists = deque(maxlen=self.window.maxlen)  # the ball distance after each of them
        self.odometry = [0.0, 0.0, 0.0]  # dead-reckoned (x, y, heading) from the commanded motions
        self.odo_hist = deque(maxlen=self.window.maxlen)  # the odometry position after each pair
        self.entry_pos: dict[int, list[tuple[float, float]]] = {}  # state -> odometry at its entries
        self.closest = float("inf")
        self.since_closer = 0
        self.entries: Counter = Counter()  # obstacle state -> entries since the last closest approach
        self.detector = ""  # the loop detector that stopped the last execution phase
        self.leg_start = 0  # interactions when the last execution phase began or last reached a target
        self.pre_states: list[int] = []  # the state each motion was chosen in (motions[i] in pre_states[i])
        self.blinded_at: int | None = None
        # --- evolution counters (saved in the checkpoint) ---
        self.generations = 0
        self.genetic_operations = 0
        self.phases: list[dict] = []
        self.target_log: list[dict] = []
        self.best_rows: np.ndarray | None = None
        self.started = False
        self.state = self.world.reset_to_start()
        self.trajectory.append((*self.world.pose[:2], "start"))
        self.wall_time_s = 0.0

    # -- the world side ------------------------------------------------------------------------

    def _advance(self, motion: int, record: bool = True):
        """Execute one motion: one interaction, one model update; relocation after a target."""
        s = self.state
        if self.mirror.crash[s, motion]:
            self.known_crash_repeats += 1
        step = self.world.step(motion)
        written = step.state
        if self.config.model_update == "most_frequent" and not step.crashed:
            seen = self.outcomes.setdefault((s, motion), {})
            seen[step.state] = seen.get(step.state, 0) + 1
            top = max(seen.values())
            if seen[step.state] < top:
                written = next(s2 for s2, n in seen.items() if n == top)
        self.evaluator.observe(s, motion, written, step.crashed)
        self.mirror.observe(s, motion, written, step.crashed)
        self.transitions.add((s, motion, step.state, step.crashed))
        self.motions.append(motion)
        self.pre_states.append(s)
        self.state_log.append(step.state)
        self.interactions += 1
        self.leg_steps += 1
        self.window.append((s, motion))
        self.dists.append(step.distance_mm)
        if not step.crashed:
            ox, oy, oh = self.odometry
            turn = math.radians(float(MOTION_ROTATION_DEG[motion]))
            move = float(MOTION_TRANSLATION_MM[motion])
            self.odometry = [ox + move * math.cos(oh + turn / 2), oy + move * math.sin(oh + turn / 2),
                             oh + turn]
        self.odo_hist.append((self.odometry[0], self.odometry[1]))
        self.curve_states.append(self.mirror.n_states)
        self.curve_transitions.append(self.mirror.n_transitions)
        x, y, _ = self.world.pose
        self.state = step.state
        if step.crashed:
            self.trajectory.append((x, y, "crash"))
        elif step.reached:
            self.trajectory.append((x, y, "target"))
            self.targets += 1
            if record:
                self.target_log.append({
                    "target": self.targets, "interactions": self.interactions,
                    "generations": self.generations, "world_states": self.mirror.n_states,
                    "transitions": self.mirror.n_transitions,
                })
            if self.config.blind_bit is not None and self.targets == self.config.blind_after_target:
                self.world.faults = (Fault(at_step=self.world.interactions, bit=self.config.blind_bit),)
                self.blinded_at = self.interactions
            self.state = self.world.relocate((self.targets - 1) % N_POSITIONS)
            self.leg_steps = 0
            self.closest, self.since_closer = float("inf"), 0
            self.entries.clear()
            self.entry_pos.clear()
            self.window.clear()
            self.dists.clear()
            self.odo_hist.clear()
            self.trajectory.append((*self.world.pose[:2], "relocate"))
        else:
            self.trajectory.append((x, y, ""))
        if step.distance_mm < self.closest - 1e-9:
            self.closest, self.since_closer = step.distance_mm, 0
            self.entries.clear()
            self.entry_pos.clear()
        else:
            self.since_closer += 1
            if self.state != s and self.state & OBSTACLE_MASK:
                radius = self.config.loop_radius_mm
                if radius:
                    x0, y0 = self.odometry[0], self.odometry[1]
                    seen = self.entry_pos.setdefault(self.state, [])
                    seen.append((x0, y0))
                    self.entries[self.state] = sum(
                        1 for x1, y1 in seen if math.hypot(x1 - x0, y1 - y0) <= radius)
                else:
                    self.entries[self.state] += 1
        return step

    def _mark(self, state: int, motion: int) -> None:
        """Write a real-world loop into the world model (option ``mark_loops``): (state, motion)
        leads back to state ("self") or crashes ("crash"). No motion is executed: no interaction."""
        crash = self.config.mark_loops == "crash"
        self.evaluator.observe(state, motion, state, crash)
        self.mirror.observe(state, motion, state, crash)
        if not crash and self.config.model_update == "most_frequent":
            self.outcomes.pop((state, motion), None)  # the loop is the outcome to remember now

    def _execute(self) -> tuple[str, int, int, int]:
        """One execution phase: (reason, steps, failing state, failing motion); reason is
        'crash', 'timeout', 'loop' or 'done'."""
        cfg = self.config
        steps = 0
        self.leg_steps = 0
        self.closest, self.since_closer = float("inf"), 0
        self.entries.clear()
        self.entry_pos.clear()
        if cfg.blame_phase_only:
            self.window.clear()
            self.dists.clear()
            self.odo_hist.clear()
        window, reentries, repeats = self.loop_limits()
        self.leg_start = self.interactions
        while True:
            s = self.state
            a = self.controller.motion(s)
            step = self._advance(a)
            steps += 1
            if step.reached:
                self.leg_start = self.interactions
                window, reentries, repeats = self.loop_limits()  # a new leg: no stops yet
                if self.progress_bar is not None:
                    self.progress_bar.update(1)
                    self.progress_bar.set_postfix(interactions=self.interactions, generations=self.generations)
                if self.targets >= cfg.n_targets:
                    return "done", steps, s, a
                continue
            if step.crashed:
                return "crash", steps, s, a
            if self.leg_steps >= cfg.max_leg_steps:
                return "timeout", steps, *self._blame()
            if window and self.since_closer >= window:
                self.detector = "window"
                return "loop", steps, *self._blame()
            if reentries and self.entries and max(self.entries.values()) >= reentries:
                self.detector = "reentries"
                return "loop", steps, *self._blame()
            if repeats and self._periodic(repeats):
                self.detector = "repeats"
                return "loop", steps, *self._blame()
            if cfg.loop_cycles and self._cycled(cfg.loop_cycles):
                self.detector = "cycles"
                return "loop", steps, *self._blame()
            if cfg.max_interactions and self.interactions >= cfg.max_interactions:
                return "budget", steps, s, a

    def loop_limits(self) -> tuple[int, int, int]:
        """The loop detectors' thresholds for the next execution phase, (loop_window,
        loop_reentries, loop_repeats), 0 = off: the config's, switched off by ``loop_patience``
        or doubled per ``loop_relax`` loop stops since the last target."""
        cfg = self.config
        stops = sum(1 for p in self.phases if p["targets"] == self.targets and p["reason"] == "loop")
        if cfg.loop_patience and stops >= cfg.loop_patience:
            return cfg.loop_window, 0, 0
        scale = 2 ** (stops // cfg.loop_relax) if cfg.loop_relax else 1
        window = cfg.loop_window * (scale if cfg.relax_window else 1)
        return window, cfg.loop_reentries * scale, cfg.loop_repeats * scale

    def _periodic(self, repeats: int) -> bool:
        """The last ``repeats * p`` pairs repeat one p-cycle (2 <= p <= 6), all since the last new
        closest approach to the ball."""
        w = self.window
        for p in range(2, 7):
            n = repeats * p
            if n > len(w) or n > self.since_closer:
                break
            tail = list(w)[-n:]
            if self.config.loop_key == "motion":
                tail = [a for _, a in tail]
            if all(tail[i] == tail[i % p] for i in range(n)) and len(set(tail[:p])) > 1:
                if self.config.loop_radius_mm:
                    (x0, y0), (x1, y1) = self.odo_hist[-n], self.odo_hist[-1]
                    if math.hypot(x1 - x0, y1 - y0) > self.config.loop_radius_mm:
                        continue  # the cycle moves the robot on: not a loop
                if not self.config.loop_still_mm:
                    return True
                # a loop goes nowhere: one cycle later the ball is as far as it was (a wall
                # followed away from the ball also repeats a cycle, but the distance drifts)
                d = list(self.dists)[-n:]
                if max(abs(d[i] - d[i - p]) for i in range(p, n)) <= self.config.loop_still_mm:
                    return True
        return False

    def _cycled(self, rounds: int) -> bool:
        """The robot is back in its current state after a simple cycle of p pairs (2 <= p <= 8:
        the states in it distinct, one with an obstacle bit), gone round ``rounds`` times in a row
        since its last new closest approach to the ball, and by odometry within
        ``loop_radius_mm`` (if set) of where the first round began."""
        w, now = self.window, self.state
        for p in range(2, 9):
            n = rounds * p
            if n > len(w) or n > self.since_closer:
                break
            if w[-p][0] != now:
                continue
            cycle = [w[i] for i in range(-p, 0)]
            states = [s for s, _ in cycle]
            if len(set(states)) < p or not any(s & OBSTACLE_MASK for s in states):
                continue
            if any(w[-p * r + i] != cycle[i] for r in range(2, rounds + 1) for i in range(p)):
                continue
            if self.config.loop_radius_mm:
                # where the first round began: the position after the pair before it (the oldest
                # one kept if the window holds no earlier pair)
                x0, y0 = self.odo_hist[max(-n - 1, -len(self.odo_hist))]
                x1, y1 = self.odo_hist[-1]
                if math.hypot(x1 - x0, y1 - y0) > self.config.loop_radius_mm:
                    continue
            return True
        return False

    def _blame(self) -> tuple[int, int]:
        """The (state, motion) a time-out or loop is blamed on: the most frequent recent pair in a
        state the controller decides (some obstacle bit set), else the last pair."""
        pairs = [p for p in self.window if p[0] & OBSTACLE_MASK]
        if not pairs:
            return self.window[-1]
        return Counter(pairs).most_common(1)[0][0]

    # -- the learning side ---------------------------------------------------------------------

    def _learn(self, reason: str, steps: int, state: int, motion: int) -> None:
        cfg = self.config
        record = {
            "phase": len(self.phases) + 1, "reason": reason, "interactions": self.interactions,
            "targets": self.targets, "execution_steps": steps, "leg_steps": self.leg_steps,
            "state": int(state), "motion": int(motion),
            "world_states": self.mirror.n_states, "model_transitions": self.mirror.n_transitions,
        }
        if reason == "loop":
            record["detector"] = self.detector  # which loop detector stopped the leg
        if reason in ("timeout", "loop"):
            record["leg_start"] = self.leg_start
        if cfg.mark_loops != "off" and reason in ("timeout", "loop") and state & OBSTACLE_MASK \
                and self.mirror.crash[state].sum() < cfg.mark_limit:
            self._mark(state, motion)
            record["marked"] = True
        if cfg.targeted and self.best_rows is not None and state & OBSTACLE_MASK:
            avoid = {motion} | set(np.flatnonzero(self.mirror.crash[state]).tolist())
            mutants = targeted_mutants(self.rng, self.best_rows, state, avoid, cfg.targeted)
            base = cfg.population - len(mutants)
            for i, rows in enumerate(mutants):
                self.ga.replace(base + i, rows)
            record["targeted"] = len(mutants)
        n_states = self.mirror.n_states
        penalised = self._leg_blames() if cfg.loop_penalty else ()
        for _ in range(cfg.generations_per_phase):
            pop = self.ga.ask()
            counts = self.evaluator.evaluate(pop)
            fitness = model_fitness(counts, n_states)
            if penalised:
                fitness = fitness - cfg.loop_penalty * _repeats(pop, penalised, cfg.reflex) / n_states
            self.ga.tell(fitness)
            self.generations += 1
            self.genetic_operations += pop.shape[0]
        last = self.ga.last_fitness
        i_best = int(np.argmax(last))
        eligible = None  # the individuals the escape allows (None: all)
        if cfg.escape and reason in ("timeout", "loop") and state & OBSTACLE_MASK:
            motions = _motions_in(pop, state, cfg.reflex)
            if cfg.escape_spread != "off":
                i_best = self._spread_escape(pop, counts, last, i_best, record)
            elif cfg.escape_memory:
                penalty = self._blames(state, motion)[motions]
                differs = penalty == penalty.min()
            else:
                differs = motions != motion
            if cfg.escape_spread == "off" and differs.any():
                eligible = differs
                if not differs[i_best]:
                    i_best = int(np.flatnonzero(differs)[np.argmax(last[differs])])
                    record["escaped"] = True
        if cfg.download == "closest" and self.best_rows is not None and cfg.escape_spread == "off":
            i_best = self._closest(pop, last, i_best, eligible, record)
        best = pop[i_best]
        if cfg.escape_rewrite and reason in ("timeout", "loop") and state & OBSTACLE_MASK:
            best = self._rewrite_escape(pop[int(np.argmax(last))], counts, int(np.argmax(last)), best, record)
        if cfg.escape_credit:
            fit = int(np.argmax(last))
            if not (cfg.escape_rewrite and record.get("rewritten")):
                best = pop[self._credit_choice(pop, counts, last, fit, record)]
        self.best_rows = best.copy()
        self.controller.load(best)
        record.update({
            "best_fitness": round(float(last[i_best]), 6),
            "best_crashes": int(counts.crashes[i_best]), "best_loops": int(counts.loops[i_best]),
            "best_distance": int(counts.distance[i_best]),
            "new_motion": int(self.controller.motion(state)),
            "changed": int(self.controller.motion(state)) != int(motion),
            "population_avoids": float(np.mean(
                [m != motion for m in _motions_in(self.ga.ask(), state, cfg.reflex)])),
        })
        record.update(diversity(pop, self.mirror.states))
        self.phases.append(record)

    def _closest(self, pop, fitness, i_best: int, eligible, record: dict) -> int:
        """Among the individuals tied with ``i_best`` (and ``eligible``, if given), the one whose
        motions differ from the running controller's in the least visited states (download
        "closest"); ties: the first."""
        ties = fitness == fitness[i_best]
        if eligible is not None:
            ties &= eligible
        index = np.flatnonzero(ties)
        if len(index) == 1:
            return i_best
        current = truth_tables(self.best_rows[None], reflex=self.config.reflex)[0]
        tables = truth_tables(pop[index], reflex=self.config.reflex)
        visits = np.bincount(self.pre_states, minlength=256)  # steps taken in each state
        cost = ((tables != current) * visits).sum(axis=1)
        record["ties"] = len(index)
        return int(index[np.argmin(cost)])

    def _leg_blames(self) -> list[tuple[int, int]]:
        """Option ``loop_penalty``: the distinct obstacle (state, motion) pairs blamed for the
        loops and time-outs of the earlier phases of the current leg (since the last target)."""
        return sorted({(p["state"], p["motion"]) for p in self.phases
                       if p["reason"] in ("timeout", "loop") and p["state"] & OBSTACLE_MASK
                       and p["targets"] == self.targets})

    def _spread_escape(self, pop, counts, fitness, i_best: int, record: dict) -> int:
        """Option ``escape_spread``: among the individuals no worse than the fittest on the model's
        crashes and loops, the one whose motions repeat the fewest of the failing phase's obstacle
        steps (ties: the fittest of them)."""
        steps = self._failed_steps(self.config.escape_spread)
        if not steps:
            return i_best
        from ga.truth_table import truth_tables

        tables = truth_tables(pop, reflex=self.config.reflex)
        states = np.array([s for s, _ in steps], dtype=np.int64)
        motions = np.array([a for _, a in steps], dtype=np.int64)
        weights = np.array(list(steps.values()), dtype=np.int64)
        repeats = ((tables[:, states] == motions) * weights).sum(axis=1)
        ok = (counts.crashes <= counts.crashes[i_best]) & (counts.loops <= counts.loops[i_best])
        cand = np.flatnonzero(ok)
        order = np.lexsort((-fitness[cand], repeats[cand]))
        chosen = int(cand[order[0]])
        record["repeated_steps"] = [int(repeats[i_best]), int(repeats[chosen]), int(weights.sum())]
        if chosen != i_best:
            record["escaped"] = True
        return chosen

    def _blame_table(self, current: dict | None = None) -> np.ndarray:
        """(256, 8) blame of every (state, motion): steps in legs failed by a time-out or loop
        minus steps in legs that reached the target (rebuilt from the records: resume-safe)."""
        blame = np.zeros((256, 8), dtype=np.int64)
        s, a = np.array(self.pre_states, dtype=np.int64), np.array(self.motions, dtype=np.int64)
        ends = sorted([p["interactions"] for p in self.phases])
        for p in self.phases + ([current] if current else []):
            if "leg_start" in p:
                np.add.at(blame, (s[p["leg_start"]:p["interactions"]], a[p["leg_start"]:p["interactions"]]), 1)
        last = 0
        for rec in self.target_log:
            end = rec["interactions"]
            start = max([last] + [e for e in ends if e < end])
            np.add.at(blame, (s[start:end], a[start:end]), -1)
            last = end
        return blame

    def _credit_choice(self, pop, counts, fitness, i_fit: int, record: dict) -> int:
        """Option ``escape_credit``: the index to download."""
        from ga.truth_table import truth_tables

        blame = np.maximum(self._blame_table(record), 0)
        states = np.array([q for q in self.mirror.states if q & OBSTACLE_MASK], dtype=np.int64)
        if states.size == 0 or not blame.any():
            return i_fit
        tables = truth_tables(pop, reflex=self.config.reflex)[:, states]
        penalty = blame[states[None, :], tables].sum(axis=1)
        ok = np.flatnonzero((counts.crashes <= counts.crashes[i_fit]) & (counts.loops <= counts.loops[i_fit]))
        chosen = int(ok[np.lexsort((-fitness[ok], penalty[ok]))[0]])
        record["blame"] = [int(penalty[i_fit]), int(penalty[chosen])]
        return chosen

    def _failed_steps(self, mode: str) -> Counter:
        """The obstacle (state, motion) steps of the failed leg ("leg") or of every leg failed by
        a time-out or loop since the last target ("target")."""
        spans = [(self.leg_start, self.interactions)]
        if mode == "target":
            spans += [(p["leg_start"], p["interactions"]) for p in self.phases
                      if p["targets"] == self.targets and "leg_start" in p]
        return Counter((self.pre_states[i], self.motions[i]) for lo, hi in spans for i in range(lo, hi)
                       if self.pre_states[i] & OBSTACLE_MASK)

    def _rewrite_escape(self, fittest, counts, i_fit: int, fallback, record: dict) -> np.ndarray:
        """Option ``escape_rewrite``: copies of ``fittest`` with new motions in the failed leg's
        most visited obstacle states; the fittest copy no worse on the model's crashes and loops
        (else ``fallback``, the plain escape's choice)."""
        from ga.operators import set_state_motion

        leg = Counter()
        for (s, _a), n in self._failed_steps("leg").items():
            leg[s] += n
        states = [s for s, n in leg.most_common(4) if n >= 2]
        if not states:
            return fallback
        tried = {s: set(np.flatnonzero(self.mirror.crash[s]).tolist()) for s in states}
        for (s, a) in self._failed_steps("target"):
            if s in tried:
                tried[s].add(a)
        copies = []
        for _ in range(self.config.escape_rewrite):
            rows = fittest.copy()
            for s in states:
                free = ([m for m in range(8) if m not in tried[s]]
                        or [m for m in range(8) if not self.mirror.crash[s, m]] or list(range(8)))
                rows = set_state_motion(self.rng, rows, s, int(self.rng.choice(free)))
            copies.append(rows)
        copies = np.stack(copies)
        got = self.evaluator.evaluate(copies)
        self.genetic_operations += copies.shape[0]
        fit = model_fitness(got, self.mirror.n_states)
        ok = (got.crashes <= counts.crashes[i_fit]) & (got.loops <= counts.loops[i_fit])
        record["rewritten_states"] = [int(s) for s in states]
        if not ok.any():
            return fallback
        i = int(np.flatnonzero(ok)[np.argmax(fit[ok])])
        self.ga.replace(self.config.population - 1, copies[i])
        record["escaped"] = record["rewritten"] = True
        return copies[i]

    def _blames(self, state: int, motion: int) -> np.ndarray:
        """Per motion, how often it was blamed for a time-out or loop in ``state`` (the phase
        records and this one), plus 1,000 where the model knows it crashes there."""
        blames = np.zeros(8, dtype=np.int64)
        for p in self.phases:
            if p["reason"] in ("timeout", "loop") and p["state"] == state:
                blames[p["motion"]] += 1
        blames[motion] += 1
        blames += 1000 * self.mirror.crash[state].astype(np.int64)
        return blames

    # -- the lifetime --------------------------------------------------------------------------

    progress_bar = None

    def run(self, stop_after_phases: int | None = None) -> "OnlineRun":
        cfg = self.config
        t0 = time.perf_counter()
        if self.progress:
            from tqdm import tqdm

            self.progress_bar = tqdm(total=cfg.n_targets, initial=min(self.targets, cfg.n_targets),
                                     unit="target", desc="on-line", file=sys.stderr)
        try:
            if not self.started:
                # Empty model: a random individual of the initial population drives.
                pop = self.ga.ask()
                self.best_rows = pop[int(self.rng.integers(pop.shape[0]))].copy()
                self.controller.load(self.best_rows)
                self.started = True
            while self.targets < cfg.n_targets:
                if stop_after_phases is not None and len(self.phases) >= stop_after_phases:
                    break
                reason, steps, s, a = self._execute()
                if reason in ("done", "budget"):
                    break
                self._learn(reason, steps, s, a)
                self.wall_time_s += time.perf_counter() - t0
                t0 = time.perf_counter()
                if self.checkpoint_path is not None:
                    self.save(self.checkpoint_path)
        finally:
            self.wall_time_s += time.perf_counter() - t0
            if self.progress_bar is not None:
                self.progress_bar.close()
                self.progress_bar = None
        return self

    # -- checkpoints ---------------------------------------------------------------------------

    def state_dict(self) -> dict:
        return {
            "motions": bytes(self.motions).hex(),
            "interactions": self.interactions,
            "targets": self.targets,
            "generations": self.generations,
            "genetic_operations": self.genetic_operations,
            "phases": self.phases,
            "target_log": self.target_log,
            "best_rows": None if self.best_rows is None else hex_from_rows(self.best_rows),
            "started": self.started,
            "ga": self.ga.state_dict(),
            "wall_time_s": self.wall_time_s,
        }

    def save(self, path: Path) -> None:
        save_checkpoint(path, CHECKPOINT_KIND, self.config.to_dict(), self.state_dict())

    def load_state(self, d: dict) -> None:
        """Continue from ``state_dict`` output: replay the motions through world and evaluator."""
        if self.interactions:
            raise RuntimeError("load_state needs a fresh OnlineRun")
        marks: dict[int, list[tuple[int, int]]] = {}
        for p in d["phases"]:
            if p.get("marked"):
                marks.setdefault(p["interactions"], []).append((p["state"], p["motion"]))
        for motion in bytes.fromhex(d["motions"]):
            self._advance(motion, record=False)
            for s, a in marks.get(self.interactions, ()):
                self._mark(s, a)
        if self.interactions != d["interactions"] or self.targets != d["targets"]:
            raise CheckpointError(
                f"replaying the checkpoint's motions gave {self.interactions} interactions and "
                f"{self.targets} targets, the checkpoint says {d['interactions']} and {d['targets']}"
            )
        self.generations = int(d["generations"])
        self.genetic_operations = int(d["genetic_operations"])
        self.phases = list(d["phases"])
        self.target_log = list(d["target_log"])
        self.started = bool(d["started"])
        self.wall_time_s = float(d["wall_time_s"])
        self.ga = GeneticAlgorithm.from_state_dict(d["ga"], self.rng)
        if d["best_rows"] is not None:
            self.best_rows = rows_from_hex(d["best_rows"])
            self.controller.load(self.best_rows)

    # -- results -------------------------------------------------------------------------------

    def summary(self) -> dict:
        """The off-line summary's keys plus the on-line ones (phases and their reasons)."""
        cfg = self.config
        reasons = Counter(p["reason"] for p in self.phases)
        lost = sum(p["leg_steps"] for p in self.phases if p["reason"] in ("timeout", "loop"))
        at64 = next((t for t in self.target_log if t["target"] == min(64, cfg.n_targets)), None)
        out = {
            "method": "online-model-based",
            "backend": self.backend,
            "seed": cfg.seed,
            "arena": cfg.arena,
            "interactions": self.interactions,
            "generations": self.generations,
            "genetic_operations": self.genetic_operations,
            "world_states": self.mirror.n_states,
            # As the off-line summary: transitions = distinct (state, motion) pairs met (the
            # world model's entries); transition_outcomes = distinct (s, a, s2, crashed) seen.
            "transitions": self.mirror.n_transitions,
            "transition_outcomes": len(self.transitions),
            "targets_reached": self.targets,
            "best_genome": None if self.best_rows is None else hex_from_rows(self.best_rows),
            "wall_time_s": round(self.wall_time_s, 3),
            "learning_phases": len(self.phases),
            "phase_reasons": dict(sorted(reasons.items())),
            "interactions_lost_to_timeouts": lost,
            "known_crash_repeats": self.known_crash_repeats,
            "crashes": sum(1 for p in self.phases if p["reason"] == "crash"),
            "board_cycles": {"controller": int(getattr(self.controller, "cycles", 0)),
                             "evaluator": int(getattr(self.evaluator, "cycles", 0))},
            "config": cfg.to_dict(),
            "phases": self.phases,
            "targets": self.target_log,
        }
        if at64 is not None and cfg.n_targets > 64:
            out["at_64_targets"] = at64
        if self.blinded_at is not None:
            out["adaptation"] = adaptation_figures(self.target_log, cfg.blind_after_target, self.blinded_at)
        from cosim.hardware_time import hardware_figures  # EHW time at the FPGA clock (issue 7)

        out["hardware"] = hardware_figures(self)
        return out


def _motions_in(pop: np.ndarray, state: int, reflex: bool) -> np.ndarray:
    return truth_tables(pop, reflex=reflex)[:, state]


def _repeats(pop: np.ndarray, pairs, reflex: bool) -> np.ndarray:
    """How many of the (state, motion) ``pairs`` each controller of ``pop`` would choose."""
    tables = truth_tables(pop, reflex=reflex)
    return sum((tables[:, s] == a).astype(np.int64) for s, a in pairs)


def adaptation_figures(target_log: list[dict], after: int, blinded_at: int, window: int = 8) -> dict:
    """Interactions from the blinding to each of the next ``window`` targets."""
    later = [t for t in target_log if after < t["target"] <= after + window]
    return {
        "blinded_after_target": after,
        "blinded_at_interaction": blinded_at,
        "targets_after": len(later),
        "interactions_for_next_targets": (later[-1]["interactions"] - blinded_at) if len(later) == window else None,
        "per_target": [t["interactions"] - blinded_at for t in later],
    }


def make_run(config: OnlineConfig, backend: str = "reference", out: Path | None = None,
             resume: bool = False, progress: bool = False) -> OnlineRun:
    """A run on fresh boards of ``backend``; with ``resume``, continued from ``out/checkpoint.json``."""
    controller, evaluator = make_boards(backend, reflex=config.reflex, distance_rule=config.distance_rule)
    ckpt = None if out is None else Path(out) / "checkpoint.json"
    run = OnlineRun(config, controller, evaluator, checkpoint=ckpt, progress=progress, backend=backend)
    if resume:
        if ckpt is None:
            raise CheckpointError("--resume needs an output directory holding checkpoint.json")
        run.load_state(load_checkpoint(ckpt, CHECKPOINT_KIND, config.to_dict()))
    return run


# -- reporting -----------------------------------------------------------------------------------


def summary_table(summary: dict) -> str:
    """The figures beside the paper's (section 5.2)."""
    rows = [("targets reached", "targets_reached"), ("interactions", "interactions"),
            ("generations", "generations"), ("genetic operations", "genetic_operations"),
            ("world states", "world_states"), ("transitions", "transitions")]
    at64 = summary.get("at_64_targets")
    lines = [f"{'':22s}{'this run':>14s}{'paper':>12s}", "-" * 48]
    for label, key in rows:
        value = summary[key]
        if at64 is not None:  # the figures at the 64th target; the continued run follows below
            value = {"targets_reached": at64["target"],
                     "genetic_operations": at64["generations"] * summary["config"]["population"]
                     }.get(key, at64.get(key))
        lines.append(f"{label:22s}{value:>14,}{PAPER[key]:>12,}")
    lines.append(f"{'learning phases':22s}{summary['learning_phases']:>14,}{'~48':>12s}")
    if at64 is not None:
        lines.append(f"continued to {summary['targets_reached']} targets: {summary['interactions']:,} "
                     f"interactions, {summary['generations']:,} generations (Fig. 11)")
    reasons = ", ".join(f"{k} {v}" for k, v in summary["phase_reasons"].items())
    lines.append(f"phase reasons: {reasons}; wall time {summary['wall_time_s']:.1f} s")
    if summary["config"].get("distance_rule", "covered") != "covered":
        lines.append(f"fitness distance term: dist[a] = {summary['config']['distance_rule']} "
                     "(NOT the SPEC's dist[a]; docs/online.md, round 5)")
    if "adaptation" in summary:
        ad = summary["adaptation"]
        lines.append(f"adaptation: IR bit {summary['config']['blind_bit']} blinded after target "
                     f"{ad['blinded_after_target']}: {ad['interactions_for_next_targets']} interactions "
                     f"for the next 8 targets")
    if summary.get("hardware"):
        from cosim.hardware_time import hardware_line

        lines.append(hardware_line(summary))
    return "\n".join(lines)


def write_plots(run: OnlineRun, out: Path) -> list[Path]:
    """Fig. 9 (trajectory), Fig. 10 (targets vs generations, states/transitions vs interactions),
    Fig. 11 when the run went past 64 targets."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from sim_world.render import plot_trajectory

    out.mkdir(parents=True, exist_ok=True)
    paths = []
    title = (f"On-line model-based lifetime (seed {run.config.seed}): {run.targets} targets, "
             f"{run.interactions:,} interactions")
    path = out / "fig9_trajectory.png"
    plot_trajectory(run.world.arena, [(x, y, 0.0, event) for x, y, event in run.trajectory], path,
                    title=title)
    paths.append(path)

    def fig10(limit: int | None, name: str, title: str):
        log = [t for t in run.target_log if limit is None or t["target"] <= limit]
        n = log[-1]["interactions"] if (limit is not None and log) else run.interactions
        fig, (a1, a2) = plt.subplots(1, 2, figsize=(12, 4.5))
        gens = [0] + [t["generations"] for t in log]
        a1.step(gens, list(range(len(log) + 1)), where="post")
        a1.set_xlabel("generations")
        a1.set_ylabel("targets reached")
        a1.grid(alpha=0.3)
        x = np.arange(1, n + 1)
        a2.plot(x, run.curve_states[:n], label="world states")
        a2.plot(x, run.curve_transitions[:n], label="transitions")
        for t in log:
            a2.axvline(t["interactions"], color="0.85", lw=0.5, zorder=0)
        if limit is None and run.config.n_targets > 64:
            t64 = next((t for t in log if t["target"] == 64), None)
            if t64:
                a1.axvline(t64["generations"], color="r", ls="--", lw=1)
                a2.axvline(t64["interactions"], color="r", ls="--", lw=1, label="64th target")
        a2.set_xlabel("interactions (grey: a target reached)")
        a2.legend()
        a2.grid(alpha=0.3)
        fig.suptitle(title)
        paths.append(out / name)
        fig.savefig(paths[-1], dpi=110, bbox_inches="tight")
        plt.close(fig)

    fig10(64, "fig10_targets_states.png", "Targets vs generations; states and transitions vs interactions")
    if run.config.n_targets > 64:
        fig10(None, "fig11_continued.png", f"Continued past 64 targets ({run.targets} targets)")
    return paths


def write_results(run: OnlineRun, out: Path, plots: bool = True) -> dict:
    out.mkdir(parents=True, exist_ok=True)
    summary = run.summary()
    (out / "summary.json").write_text(json.dumps(summary, indent=1) + "\n")
    if plots:
        summary["plots"] = [str(p) for p in write_plots(run, out)]
    return summary


# -- command line --------------------------------------------------------------------------------


def config_from_args(args) -> OnlineConfig:
    return OnlineConfig(
        seed=args.seed, arena=args.arena, n_targets=args.targets + args.continue_past_64,
        population=args.population, generations_per_phase=args.generations_per_phase,
        max_leg_steps=args.max_leg_steps, loop_window=args.loop_window,
        loop_reentries=args.loop_reentries, loop_repeats=args.loop_repeats, targeted=args.targeted, mark_limit=args.mark_limit,
        max_interactions=args.max_interactions,
        escape=args.escape, escape_memory=args.escape_memory,
        blame_phase_only=args.blame_phase_only, loop_key=args.loop_key,
        loop_still_mm=args.loop_still_mm, loop_patience=args.loop_patience,
        escape_rewrite=args.escape_rewrite, escape_credit=args.escape_credit, loop_penalty=args.loop_penalty, loop_relax=args.loop_relax, loop_radius_mm=args.loop_radius_mm, relax_window=args.relax_window, escape_spread=args.escape_spread,
        mark_loops=args.mark_loops, model_update=args.model_update,
        loop_cycles=args.loop_cycles, download=args.download, distance_rule=args.distance,
        blind_bit=args.blind_bit, blind_after_target=args.blind_after_target,
    )


def build_parser() -> argparse.ArgumentParser:
    d = OnlineConfig()
    p = argparse.ArgumentParser(prog="python -m cosim.online", description=__doc__.split("\n")[0])
    p.add_argument("--backend", choices=BACKENDS, default="reference",
                   help="the boards: NumPy reference, Amaranth's simulator, or cocotb on the Verilog "
                        "(simulator: EHW_SIM=icarus|verilator, default icarus; HDL_SAMPLE: "
                        "EHW_HDL_SAMPLE=k evaluates k controllers a population on the HDL, 0 = all)")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--arena", default=d.arena)
    p.add_argument("--out", type=Path, default=Path("results/model_based"))
    p.add_argument("--resume", action="store_true", help="continue from <out>/checkpoint.json")
    p.add_argument("--targets", type=int, default=64, help="targets of the lifetime (default 64)")
    p.add_argument("--continue-past-64", type=int, default=0, metavar="N",
                   help="go on for N more targets after the 64th (Fig. 11)")
    p.add_argument("--blind-bit", type=int, default=None, metavar="B", help="IR bit 0..5 to blind (stuck at 0)")
    p.add_argument("--blind-after-target", type=int, default=None, metavar="T")
    p.add_argument("--population", type=int, default=d.population)
    p.add_argument("--generations-per-phase", type=int, default=d.generations_per_phase)
    p.add_argument("--max-leg-steps", type=int, default=d.max_leg_steps)
    p.add_argument("--loop-window", type=int, default=d.loop_window)
    p.add_argument("--loop-reentries", type=int, default=d.loop_reentries)
    p.add_argument("--loop-repeats", type=int, default=d.loop_repeats)
    p.add_argument("--targeted", type=int, default=d.targeted)
    p.add_argument("--max-interactions", type=int, default=d.max_interactions,
                   help="end the lifetime after this many interactions even short of the targets (0: never)")
    p.add_argument("--escape", action=argparse.BooleanOptionalAction, default=d.escape)
    p.add_argument("--blame-phase-only", action=argparse.BooleanOptionalAction,
                   default=d.blame_phase_only,
                   help="blame a loop only on the pairs of the failing execution phase")
    p.add_argument("--loop-key", choices=("pair", "motion"), default=d.loop_key,
                   help="what --loop-repeats compares: (state, motion) pairs or motions only")
    p.add_argument("--loop-still-mm", type=float, default=d.loop_still_mm,
                   help="--loop-repeats fires only if the ball distance one cycle apart changes "
                        "by at most this (mm; 0: off)")
    p.add_argument("--loop-patience", type=int, default=d.loop_patience,
                   help="after this many loop stops at one target, only --loop-window stops a leg "
                        "until the next target (0: off)")
    p.add_argument("--loop-relax", type=int, default=d.loop_relax,
                   help="after every K loop stops at one target, double the loop detectors' "
                        "thresholds until the next target (0: off)")
    p.add_argument("--escape-spread", choices=("off", "leg", "target"), default=d.escape_spread,
                   help="escape downloads the individual (no worse on model crashes/loops) that "
                        "repeats the fewest obstacle steps of the failed leg (leg) or of every "
                        "failed leg since the last target (target)")
    p.add_argument("--loop-radius-mm", type=float, default=d.loop_radius_mm,
                   help="loop_reentries/loop_repeats fire only if the robot is back within this "
                        "distance by odometry (commanded motions; 0: off)")
    p.add_argument("--distance", choices=DISTANCE_RULES, default=d.distance_rule,
                   help="dist[a] of the model-based fitness: covered = SPEC section 7 (backward "
                        "steps count); forward = NOT the SPEC, only forward translation counts "
                        "(docs/online.md, round 5)")
    p.add_argument("--loop-cycles", type=int, default=d.loop_cycles, metavar="K",
                   help="stop a leg once the robot has gone K times round one simple cycle of "
                        "states back to where it is, within --loop-radius-mm (0: off)")
    p.add_argument("--download", choices=("first", "closest"), default=d.download,
                   help="which of the individuals tied for the best fitness is downloaded: the "
                        "first, or the one that changes the motion of the least visited states")
    p.add_argument("--escape-rewrite", type=int, default=d.escape_rewrite, metavar="M",
                   help="after a loop/time-out, download the fittest of M copies of the best with "
                        "new motions in the failed leg's most visited obstacle states (0: off)")
    p.add_argument("--escape-credit", action=argparse.BooleanOptionalAction, default=d.escape_credit,
                   help="at every download prefer (no worse on model crashes/loops) the individual "
                        "whose motions were least often in failed legs (lifetime blame)")
    p.add_argument("--loop-penalty", type=float, default=d.loop_penalty, metavar="W",
                   help="NOT the SPEC fitness: subtract W/N for each loop-blamed (state, motion) of "
                        "the current leg that a controller would choose again (0: off)")
    p.add_argument("--relax-window", action=argparse.BooleanOptionalAction, default=d.relax_window,
                   help="--loop-relax also doubles --loop-window")
    p.add_argument("--escape-memory", action=argparse.BooleanOptionalAction, default=d.escape_memory,
                   help="escape avoids every motion blamed for a loop in the blamed state so far")
    p.add_argument("--mark-loops", choices=("off", "self", "crash"), default=d.mark_loops,
                   help="write a time-out/loop into the world model at the blamed (state, motion): "
                        "as a self-transition or a crash (not SPEC; off = SPEC)")
    p.add_argument("--model-update", choices=("most_recent", "most_frequent"), default=d.model_update,
                   help="world-model update: most_recent = SPEC section 7; most_frequent = option")
    p.add_argument("--mark-limit", type=int, default=d.mark_limit)
    p.add_argument("--no-plots", action="store_true")
    p.add_argument("--no-progress", action="store_true")
    return p


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    config = config_from_args(args)
    if args.backend == "cocotb":
        # The loop must run inside the cocotb simulation: that module launches it (in a thread).
        from cosim.cocotb_backend import main_from_args

        return main_from_args(args, config)
    if args.backend in ("serial", "uart"):  # the host link: cosim.link_boards launches both
        from cosim.link_boards import main_from_args

        return main_from_args(args, config)
    try:
        run = make_run(config, args.backend, args.out, resume=args.resume, progress=not args.no_progress)
    except CheckpointError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    run.run()
    summary = write_results(run, args.out, plots=not args.no_plots)
    print(summary_table(summary))
    print(f"wrote {args.out / 'summary.json'}" + (f" and {len(summary.get('plots', []))} plots" if not args.no_plots else ""))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""The on-line model-based method (paper section 5.2, SPEC section 7): one robot lifetime.

    ehw sim --seed 1 [--backend reference|amaranth|cocotb|serial|uart] [--resume] ...
    (make sim; the options: cosim.cli.online)

A lifetime alternates two phases, in sequence as in the paper:

- **Execution phase** (:meth:`OnlineRun.execute`). The controller board drives the robot in the
  noisy world: per step, ``a = controller.motion(s)``, one ``World.step(a)`` (one *interaction*),
  and ``evaluator.observe(s, a, s2, crashed)`` updates the world model on the evaluator board.
  Reaching the target relocates the robot to the next position of the course
  (``sim_world.course.Course``). The phase ends on a *failure*: a crash, or one of the failure
  detectors of ``cosim.online.failures`` (the leg time-out, the no-progress window, re-entries, repeated
  cycles, one round of a simple state cycle).
- **Learning phase** (:meth:`OnlineRun.learn`). ``generations_per_phase`` generations of the GA
  (population 500, tournament 20, elitism; the GA is kept across phases), each population
  evaluated on the evaluator board and scored with the normative fitness
  (``ga.evaluator.fitness``), with ``fail_rates`` less the robot's own failure rates of the
  controller's motions (``ga.fail_rates``: the host marks the pairs before each failure and
  writes the changed rate codes to the board before the phase); the controller chosen by
  ``cosim.online.download`` (the best, or after a time-out or loop the best that escapes the blamed
  motion: for a cycle stop a pair of the cycle, ``loop_blame``) is loaded with ``controller.load``.
- At the very start the model is empty and a random individual of the initial population drives.
- Stop at ``n_targets`` targets (64; more with ``--continue-past-64``) or ``max_interactions``.

The loop calls the boards only through the interfaces of ``cosim.boards.interfaces``; it is synchronous and
keeps no global state, so an HDL backend (or a cocotb test running it in a thread) plugs in.

Checkpoint and resume: after every learning phase the GA state, the counters, the phase records and
the log of executed motions go to ``<out>/checkpoint.json``. ``--resume`` rebuilds the world and
the evaluator board by replaying the logged motions (the world is deterministic for its seed), so a
resumed run is the uninterrupted run, bit for bit.
"""

from __future__ import annotations

import dataclasses
import sys
import time
from pathlib import Path

import numpy as np

from base.checkpoint import CheckpointError, load_checkpoint, save_checkpoint
from cosim.boards.registry import BackendUnavailable, learning_top_drives, make_boards, make_learning_boards
from cosim.online.config import OnlineConfig
from cosim.online.download import choose_download
from cosim.online.failures import Track, blame, blame_cycle
from ga.diversity import diversity
from ga.evaluator import fitness as model_fitness
from ga.evolution import GeneticAlgorithm
from ga.fail_rates import FailureMarks
from ga.genome import hex_from_rows, rows_from_hex
from ga.motions import OBSTACLE_MASK
from ga.truth_table import truth_tables
from ga.world_model import WorldModel
from sim_world.course import Course
from sim_world.world import Fault, World

CHECKPOINT_KIND = "online"
FAILURES = ("crash", "timeout", "loop")  # the reasons a learning phase follows a failure


def _seeds(seed: int) -> tuple[int, np.random.Generator]:
    """The world's noise seed and the GA's generator, both derived from the run's seed."""
    world_seq, ga_seq = np.random.SeedSequence(seed).spawn(2)
    return int(world_seq.generate_state(1)[0]), np.random.default_rng(ga_seq)


class OnlineRun:
    """One robot lifetime of the on-line model-based method on a (controller, evaluator) board pair.

    ``run()`` goes to ``config.n_targets`` targets (or ``stop_after_phases`` learning phases);
    ``summary()`` gives the figures. Host-side bookkeeping (state set, transitions met, a mirror
    of the world model for the figures) never feeds the boards: the evaluator board holds its own
    model, updated only by ``observe``.
    """

    progress_bar = None

    def __init__(self, config: OnlineConfig, controller, evaluator, checkpoint: Path | None = None,
                 progress: bool = False, backend: str = "reference"):
        self.config = config
        self.controller, self.evaluator = controller, evaluator
        self.checkpoint_path, self.progress, self.backend = checkpoint, progress, backend
        world_seed, self.rng = _seeds(config.seed)
        self.world = World(config.arena, noise=config.world_noise(), seed=world_seed)
        self.course = Course.of(self.world)
        self.ga = GeneticAlgorithm(config.ga_config(), self.rng)
        if controller is not None:  # None: a learner top's, set by make_run (its reflex set there)
            controller.set_reflex(config.reflex)
        self.detectors = config.detectors()
        self.timeout = self.detectors[0]
        self.track = Track(maxlen=max(config.loop_window, 64))
        self.marks = FailureMarks(mirror=config.rate_mirror, progress=config.progress_weight) if config.fail_rates else None
        # lifetime counters (rebuilt by replay on resume)
        self.motions: list[int] = []  # every motion executed, in order (the replay log)
        self.state_log: list[int] = []  # the state observed after each motion
        self.interactions = self.targets = 0
        self.mirror = WorldModel()  # host copy of the model (figures only)
        self.transitions: set[tuple[int, int, int, bool]] = set()
        self.trajectory: list[tuple[float, float, float, int, str]] = []  # (x, y, heading, state, event)
        self.curve_states: list[int] = []  # |S| after each interaction
        self.curve_transitions: list[int] = []
        self.known_crash_repeats = 0  # motions chosen in a state where the model knows they crash
        self.leg_start = 0  # interactions when the execution phase began or last reached a target
        self.blinded_at: int | None = None
        # evolution counters (saved in the checkpoint)
        self.generations = self.genetic_operations = 0
        self.phases: list[dict] = []
        self.target_log: list[dict] = []
        self.best_rows: np.ndarray | None = None
        self.started = False
        self.state = self.world.reset_to_start()
        self.trajectory.append((*self.world.pose, self.state, "start"))
        self.wall_time_s = 0.0

    # -- the execution phase -------------------------------------------------------------------

    def step(self, motion: int, record: bool = True):
        """Execute one motion: one interaction, one model update; relocation after a target."""
        s, before = self.state, self.world.camera_range()  # never the exact distance
        self.known_crash_repeats += int(self.mirror.crash[s, motion])
        step = self.world.step(motion)
        self.evaluator.observe(s, motion, step.state, step.crashed)
        self.mirror.observe(s, motion, step.state, step.crashed)
        self.transitions.add((s, motion, step.state, step.crashed))
        self.motions.append(motion)
        self.state_log.append(step.state)
        self.interactions += 1
        self.curve_states.append(self.mirror.n_states)
        self.curve_transitions.append(self.mirror.n_transitions)
        x, y, h = self.world.pose
        self.state = step.state
        reached = step.reached and not step.crashed  # (a crash restores the pose: never both)
        if self.marks is not None:
            self.marks.executed_pair(s, motion, reached, before, step.range_mm)
        if step.crashed:
            self.trajectory.append((x, y, h, step.state, "crash"))
        elif reached:
            self.trajectory.append((x, y, h, step.state, "target"))
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
            self.state = self.course.relocate(self.world, self.targets)
            self.trajectory.append((*self.world.pose, self.state, "relocate"))
        else:
            self.trajectory.append((x, y, h, step.state, ""))
        self.track.step(s, motion, self.state, step.crashed, reached, step.range_mm)
        return step

    def execute(self) -> tuple[str, int, int, int, str]:
        """One execution phase: (reason, steps, failing state, failing motion, detector); reason
        is 'crash', 'timeout', 'loop', 'done' (n_targets reached) or 'budget'."""
        cfg = self.config
        steps = 0
        self.track.new_phase()
        for detector in self.detectors:
            detector.reset()
        self.leg_start = self.interactions
        while True:
            s = self.state
            a = self.controller.motion(s)
            step = self.step(a)
            steps += 1
            fired = [detector.observe(self.track) for detector in self.detectors]
            if step.reached:
                self.leg_start = self.interactions
                for detector in self.detectors:
                    detector.reset()
                if self.progress_bar is not None:
                    self.progress_bar.update(1)
                    self.progress_bar.set_postfix(interactions=self.interactions, generations=self.generations)
                if self.targets >= cfg.n_targets:
                    return "done", steps, s, a, ""
                if extra := self.extra_stop(steps, at_target=True):
                    return extra, steps, s, a, ""
                continue
            if cfg.max_interactions and self.interactions >= cfg.max_interactions:  # before a failure
                return "budget", steps, s, a, ""
            if step.crashed:
                return "crash", steps, s, a, ""
            for detector, hit in zip(self.detectors, fired):
                if hit:
                    return (detector.reason, steps, *self.blamed(detector),
                            detector.name if detector.reason == "loop" else "")
            if extra := self.extra_stop(steps, at_target=False):
                return extra, steps, s, a, ""

    def extra_stop(self, steps: int, at_target: bool) -> str:
        """A reason to end the execution phase other than a failure, the last target or the budget,
        asked after each step (``at_target``: the step reached a target); '' = go on. None here: a
        hook for experiments (round 8 at tag research/round-18: a phase at each target, every K steps)."""
        return ""

    def blamed(self, detector) -> tuple[int, int]:
        """The (state, motion) the stop by ``detector`` is put on (the escape avoids it)."""
        cycle = getattr(detector, "cycle", None)
        if cycle and self.config.loop_blame == "cycle":
            return blame_cycle(cycle)
        return blame(self.track.pairs)

    # -- the learning phase --------------------------------------------------------------------

    def learn(self, reason: str, steps: int, state: int, motion: int, detector: str = "") -> None:
        cfg = self.config
        record = {
            "phase": len(self.phases) + 1, "reason": reason, "interactions": self.interactions,
            "targets": self.targets, "execution_steps": steps, "leg_steps": self.timeout.steps,
            "state": int(state), "motion": int(motion),
            "world_states": self.mirror.n_states, "model_transitions": self.mirror.n_transitions,
        }
        if reason == "loop":
            record["detector"] = detector
        if reason in ("timeout", "loop"):
            record["leg_start"] = self.leg_start
        if reason in FAILURES:
            self.mark_failure()
        if cfg.ga == "hardware":  # the whole phase on the learning board
            from cosim.online.learning_phase import learn_on_chip

            self.phases.append(learn_on_chip(self, record, reason, state, motion))
            return
        n_states = self.mirror.n_states
        for _ in range(cfg.generations_per_phase):
            pop = self.ga.ask()
            counts = self.evaluator.evaluate(pop)
            if self.marks is None:  # SPEC section 7's three terms: whatever the board counted
                counts = dataclasses.replace(counts, fails=None)
            self.ga.tell(model_fitness(counts, n_states))
            self.generations += 1
            self.genetic_operations += pop.shape[0]
        fitness = self.ga.last_fitness
        escape = cfg.escape and reason in ("timeout", "loop") and state & OBSTACLE_MASK
        i_best, escaped = choose_download(pop, fitness, (state, motion) if escape else None, cfg.reflex)
        if escaped:
            record["escaped"] = True
        best = pop[i_best]
        self.best_rows = best.copy()
        self.controller.load(best)
        new_motion = int(self.controller.motion(state))
        record.update({
            "best_fitness": round(float(fitness[i_best]), 6),
            "best_crashes": int(counts.crashes[i_best]), "best_loops": int(counts.loops[i_best]),
            "best_distance": int(counts.distance[i_best]), "best_fails": int(counts.fails[i_best]),
            "new_motion": new_motion, "changed": new_motion != int(motion),
            "population_avoids": float(np.mean(truth_tables(self.ga.ask(), reflex=cfg.reflex)[:, state] != motion)),
        })
        record.update(diversity(pop, self.mirror.states))
        self.phases.append(record)

    def mark_failure(self) -> None:
        """A failure ended the execution phase: mark its last pairs, write the changed rate codes."""
        if self.marks is not None:
            self.marks.failure()
            self.evaluator.write_rates(self.marks.changes())

    # -- the lifetime --------------------------------------------------------------------------

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
                reason, steps, s, a, detector = self.execute()
                if reason in ("done", "budget"):
                    break
                self.learn(reason, steps, s, a, detector)
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
            "motions": bytes(self.motions).hex(), "interactions": self.interactions,
            "targets": self.targets, "generations": self.generations,
            "genetic_operations": self.genetic_operations, "phases": self.phases,
            "target_log": self.target_log,
            "best_rows": None if self.best_rows is None else hex_from_rows(self.best_rows),
            "started": self.started, "wall_time_s": self.wall_time_s,
            # with --ga hardware the host GA only gave the initial population (rebuilt from the
            # seed): the learning board's engine is the state
            "ga": None if self.config.ga == "hardware" else self.ga.state_dict(),
            **({"learning_board": self.evaluator.state_dict()} if self.config.ga == "hardware" else {}),
        }

    def save(self, path: Path) -> None:
        save_checkpoint(path, CHECKPOINT_KIND, self.config.to_dict(), self.state_dict())

    def load_state(self, d: dict) -> None:
        """Continue from ``state_dict`` output: replay the motions through world and evaluator."""
        if self.interactions:
            raise RuntimeError("load_state needs a fresh OnlineRun")
        hardware = self.config.ga == "hardware"
        # A learning board that cannot load an engine state (the HDL engine has no port for its
        # generators and scores) gets it back by replaying the learns where they happened.
        replay = {p["interactions"]: p for p in d["phases"]} if hardware and not hasattr(
            self.evaluator, "load_state") else {}
        failures = {p["interactions"] for p in d["phases"] if p["reason"] in FAILURES}  # marks, rate writes
        for motion in bytes.fromhex(d["motions"]):
            self.step(motion, record=False)
            if self.interactions in failures:
                self.mark_failure()
            phase = replay.get(self.interactions)
            if phase is not None:
                from cosim.online.learning_phase import phase_avoid

                self.evaluator.learn(self.config.generations_per_phase,
                                     phase_avoid(self.config, phase["reason"], phase["state"], phase["motion"]))
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
        if d["ga"] is not None:
            self.ga = GeneticAlgorithm.from_state_dict(d["ga"], self.rng)
        if hardware:
            self._restore_learning_board(d["learning_board"], replayed=bool(replay))
        if d["best_rows"] is not None:
            self.best_rows = rows_from_hex(d["best_rows"])
            self.controller.load(self.best_rows)

    def _restore_learning_board(self, saved: dict, replayed: bool) -> None:
        if not replayed:
            self.evaluator.load_state(saved)
        elif getattr(self.evaluator, "state_dict", None) is not None and self.evaluator.state_dict() != saved:
            raise CheckpointError("replaying the checkpoint's learning phases on the learning board "
                                  "did not give the engine state it saved")

    # -- results -------------------------------------------------------------------------------

    def summary(self) -> dict:
        """The figures of the lifetime (``cosim.online.report.summary``)."""
        from cosim.online.report import summary

        return summary(self)


def make_run(config: OnlineConfig, backend: str = "reference", out: Path | None = None,
             resume: bool = False, progress: bool = False) -> OnlineRun:
    """A run on fresh boards of ``backend``; with ``resume``, continued from ``out/checkpoint.json``."""
    hardware = config.ga == "hardware"
    if hardware and learning_top_drives(backend):  # a learner top: both boards come with it (below)
        controller = evaluator = None
    else:
        controller, evaluator = make_boards(backend, reflex=config.reflex, distance_rule=config.distance_rule)
    ckpt = None if out is None else Path(out) / "checkpoint.json"
    run = OnlineRun(config, controller, evaluator, checkpoint=ckpt, progress=progress, backend=backend)
    if hardware:
        # The learning board takes the evaluator board's place (observe, and learn instead of
        # evaluate); it holds the host GA's initial population, so the first driver is the same.
        from cosim.online.learning_phase import hardware_ga_config, hardware_seed

        run.controller, run.evaluator = make_learning_boards(
            backend, hardware_ga_config(config), hardware_seed(config.seed), run.ga.ask(),
            controller=controller, reflex=config.reflex, distance_rule=config.distance_rule)
    if config.fail_rates and not hasattr(run.evaluator, "write_rates"):
        raise BackendUnavailable(f"--fail-rates needs an evaluator board with a rate RAM; the {backend} "
                                 f"backend's {'learning' if hardware else 'evaluator'} board has none "
                                 f"yet (use --no-fail-rates)")
    if resume:
        if ckpt is None:
            raise CheckpointError("--resume needs an output directory holding checkpoint.json")
        run.load_state(load_checkpoint(ckpt, CHECKPOINT_KIND, config.to_dict()))
    return run

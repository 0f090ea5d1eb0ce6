"""The robot's own failure rates, a fourth term of the on-line fitness (docs/research-log.md, on-line round 14).

The world model keeps one latest outcome per (state, motion); in obstacle states that outcome is
wrong about 70 % of the time in the noisy world (round 7), so a controller the model calls safe
may fail again and again. The failure rates say what each pair cost the robot, whatever the noise
did:

- **Marks** (host side, :class:`FailureMarks`). Each executed (state, motion) counts as *executed*;
  when a failure (crash, loop stop, time-out) ends an execution phase, the pairs among its last
  ``HORIZON`` steps are marked *failed* (each pair once per failure). A leg that reaches its target
  clears its pending pairs: they were fine.
- **Rate codes** (the contract with the evaluator boards, :func:`rate_codes`). The failure rate of a
  pair is (failed + prior) / (executed + 1) with prior = 0.1 for a pair never executed, written as
  an 8-bit code in units of 1 / ``RATE_ONE``: code = round((RATE_ONE failed + PRIOR_CODE) /
  (executed + 1)), 0..250. The host writes the codes that changed to the board before a learning
  phase (``write_rates`` of ``cosim.boards.interfaces.EvaluatorBoard``); a board cleared holds ``PRIOR_CODE``
  everywhere.
- **Mirror pooling** (:func:`mirror_pooled`, ``FailureMarks(mirror=True)``, the on-line default
  since round 16). The robot is left-right symmetric (``ga.motions.MIRROR_STATE``,
  ``MIRROR_MOTION``) and the world's outcome frequencies nearly so (round 12), so each pair's code
  is computed from its own counts plus those of its mirror image (a symmetric pair's counts twice):
  twice the data per code, and a failure on one side warns the other.
- **Progress deficit** (:func:`progress_codes`, ``FailureMarks(progress=w)``, the on-line default
  since round 18 with w = 3). The host also keeps each pair's summed gain towards the ball over the
  ``PROGRESS_STEPS`` steps after it (the whole distance when the leg reaches the ball first), and the
  code grows by 1.25 w per mm its mean gain falls short of the best pair of its state: of all that the
  robot learns, only its progress ranked controllers as the real world does (docs/research-log.md, on-line round 18).
- **Fail count** (the evaluator, :func:`fail_counts`). F = the sum of the codes of the controller's
  motions in the obstacle states of S, each state once: the shape of the distance term, summed
  in the same trace step. The fitness loses ``W_FAIL`` F / (N ``RATE_ONE``) (``ga.evaluator.fitness``):
  a pair that always fails weighs one crash.

``RATE_ONE`` = 10 ``W_FAIL`` D (D = 50 mm, the largest dist[a]) makes the learning engine's integer
score (``ga.hardware_ga.score``, 10 D N times the fitness) lose exactly F: no multiplier on the chip.
Measured (docs/research-log.md, on-line round 14): median interactions to 64 targets 6,620 against 8,294.5 on
held-out seeds 181-200 (float rates; the codes: round 15). The mirror pooling (round 16): 6,503
against 7,484.5 on held-out seeds 221-240, 5,804 against 6,875 on 201-220.
"""

from __future__ import annotations

import numpy as np

from ga.motions import MAX_MOTION_DISTANCE_MM, MIRROR_MOTION, MIRROR_STATE, N_MOTIONS, N_STATES, OBSTACLE_MASK

W_FAIL = 0.5  # the weight of a sure failure: a crash's (ga.evaluator.W_CRASHES)
RATE_ONE = 250  # the code of rate 1
assert RATE_ONE == round(10 * W_FAIL * MAX_MOTION_DISTANCE_MM)  # the integer score loses F exactly
PRIOR_CODE = 25  # rate 0.1 for a pair never executed (round 14: prior 0.1 chosen on seeds 1-16)
HORIZON = 8  # the steps before a failure whose pairs it marks
PROGRESS_STEPS = 8  # the steps after a pair over which its gain towards the ball is measured
RATE_BITS = 8  # one code
FAIL_BITS = 16  # F <= 256 * RATE_ONE
assert RATE_ONE < 1 << RATE_BITS and N_STATES * RATE_ONE < 1 << FAIL_BITS


def rate_codes(failed: np.ndarray, executed: np.ndarray) -> np.ndarray:
    """(256, 8) uint8: round((RATE_ONE failed + PRIOR_CODE) / (executed + 1)), halves up, in integers."""
    failed, executed = np.asarray(failed, dtype=np.int64), np.asarray(executed, dtype=np.int64)
    if failed.shape != (N_STATES, N_MOTIONS) or executed.shape != failed.shape:
        raise ValueError(f"failure marks are ({N_STATES}, {N_MOTIONS}) arrays, got {failed.shape!r} "
                         f"and {executed.shape!r}")
    if (failed < 0).any() or (failed > executed).any():
        raise ValueError("failed marks must be in 0..executed for every pair")
    den = executed + 1
    return ((2 * (RATE_ONE * failed + PRIOR_CODE) + den) // (2 * den)).astype(np.uint8)


def mirror_image(counts: np.ndarray) -> np.ndarray:
    """(256, 8) counts rearranged so that (s, a) holds those of its mirror image (m(s), m(a))
    (``ga.motions``)."""
    return np.asarray(counts)[np.ix_(MIRROR_STATE, MIRROR_MOTION)]


def mirror_pooled(counts: np.ndarray) -> np.ndarray:
    """(256, 8) counts plus those of each pair's mirror image (a symmetric pair's counts twice)."""
    return np.asarray(counts) + mirror_image(counts)


def mean_gains(gain: np.ndarray, count: np.ndarray) -> np.ndarray:
    """(256, 8) float: each pair's mean gain ``gain`` / ``count``; a pair never measured: the mean of all."""
    gain, count = np.asarray(gain, dtype=np.float64), np.asarray(count, dtype=np.float64)
    return np.where(count > 0, gain / np.maximum(count, 1.0), gain.sum() / max(count.sum(), 1.0))


def progress_codes(codes: np.ndarray, gain: np.ndarray, count: np.ndarray, weight: float) -> np.ndarray:
    """The rate codes with each pair's *progress deficit* added (docs/research-log.md, on-line round 18):
    code + round(``weight`` RATE_ONE / (W_FAIL D PROGRESS_STEPS) (g_best(s) - g(s, a))), clipped to
    0..RATE_ONE, where g is the pair's mean gain towards the ball over the PROGRESS_STEPS steps after
    it (``gain`` / ``count``; a pair never measured: the mean of all) and g_best(s) the best of its
    state's eight. In the fitness the deficit weighs ``weight`` / (N D PROGRESS_STEPS) per mm."""
    mean = mean_gains(gain, count)
    per_mm = weight * RATE_ONE / (W_FAIL * MAX_MOTION_DISTANCE_MM * PROGRESS_STEPS)
    deficit = mean.max(axis=1, keepdims=True) - mean
    return np.clip(np.floor(np.asarray(codes, dtype=np.float64) + per_mm * deficit + 0.5), 0,
                   RATE_ONE).astype(np.uint8)


def prior_codes() -> np.ndarray:
    """The codes of a cleared board: PRIOR_CODE for every pair."""
    return np.full((N_STATES, N_MOTIONS), PRIOR_CODE, dtype=np.uint8)


def fail_counts(tables: np.ndarray, states: np.ndarray, codes: np.ndarray) -> np.ndarray:
    """F of each truth table (P, 256): the summed codes of its motions in the obstacle states of
    ``states`` (S). int64 (P,)."""
    tables = np.asarray(tables)
    states = np.asarray(states, dtype=np.int64)
    obstacle = states[(states & OBSTACLE_MASK) != 0]
    codes = np.asarray(codes, dtype=np.int64)
    return codes[obstacle[None, :], tables[:, obstacle]].sum(axis=1, dtype=np.int64)


class FailureMarks:
    """The host's marks of one lifetime: executed and failed counts per (state, motion);
    ``mirror``: the codes pool each pair's counts with its mirror image's (:func:`mirror_pooled`)."""

    def __init__(self, horizon: int = HORIZON, mirror: bool = False, progress: float = 0.0):
        self.horizon = int(horizon)
        self.mirror = bool(mirror)
        self.progress = float(progress)  # the weight of the progress deficit (progress_codes); 0: none
        self.gain = np.zeros((N_STATES, N_MOTIONS))  # summed gain towards the ball (mm) per pair
        self.gain_n = np.zeros((N_STATES, N_MOTIONS))  # executions whose gain is known
        self.gain_pending: list[tuple[int, int, float, int]] = []  # (state, motion, mm before, age)
        self.executed = np.zeros((N_STATES, N_MOTIONS), dtype=np.int64)
        self.failed = np.zeros((N_STATES, N_MOTIONS), dtype=np.int64)
        self.pending: list[tuple[int, int]] = []  # this leg's pairs, not yet judged
        self.written = prior_codes()  # what the evaluator board holds

    def executed_pair(self, state: int, motion: int, reached: bool, before_mm: float = 0.0,
                      after_mm: float = 0.0) -> None:
        """One executed motion; ``reached``: it reached the target (the leg's pairs were fine);
        ``before_mm``, ``after_mm``: the distance to the ball before and after it (``progress``)."""
        self.executed[state, motion] += 1
        self.pending.append((int(state), int(motion)))
        if reached:
            self.pending.clear()
        if self.progress:
            now = 0.0 if reached else float(after_mm)
            keep = []
            for s, a, d0, age in [*self.gain_pending, (int(state), int(motion), float(before_mm), 0)]:
                if reached or age + 1 >= PROGRESS_STEPS:  # its gain is known: add it
                    self.gain[s, a] += d0 - now
                    self.gain_n[s, a] += 1
                else:
                    keep.append((s, a, d0, age + 1))
            self.gain_pending = keep

    def failure(self) -> None:
        """A failure ended the execution phase: its last ``horizon`` pairs failed, once each."""
        for s, a in set(self.pending[-self.horizon:]):
            self.failed[s, a] += 1
        self.pending.clear()

    def codes(self) -> np.ndarray:
        pool = mirror_pooled if self.mirror else np.asarray
        codes = rate_codes(pool(self.failed), pool(self.executed))
        if self.progress:
            return progress_codes(codes, pool(self.gain), pool(self.gain_n), self.progress)
        return codes

    def changes(self) -> list[tuple[int, int, int]]:
        """The (state, motion, code) the board does not hold yet, in address order; they count as
        written from now on."""
        codes = self.codes()
        states, motions = np.nonzero(codes != self.written)
        self.written = codes
        return [(int(s), int(a), int(codes[s, a])) for s, a in zip(states, motions)]

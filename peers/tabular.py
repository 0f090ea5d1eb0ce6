"""Tabular reinforcement learners: Q-learning, Dyna-Q, Dyna-Q+ and prioritized sweeping.

All three share one protocol, so the robot lifetime (:mod:`peers.lifetime`) and the test maze
(:mod:`peers.maze`) drive any of them the same way::

    a = learner.act(s)                   # epsilon-greedy over the actions allowed in s
    learner.observe(s, a, r, s2, done)   # one real transition: learning (and planning) here

* ``allowed[s]`` lists the actions the agent may take in state s. Under the paper's reflex
  (SPEC section 6) a reflex state allows only its reflex motion, so the backed-up value of a
  reflex state is the value of the motion the robot will really take there.
* The Q-table starts at ``q_init`` everywhere (optimism drives exploration besides epsilon).
* ``done`` marks a transition that ends the task (the maze's goal, the robot's target: the
  robot is then relocated, which its action did not cause): its backup has no successor value.
  Otherwise the task continues; the discount ``gamma`` < 1 keeps the values finite.
* Every random choice comes from the learner's own ``numpy.random.Generator`` (``rng``); ties
  in the greedy choice are broken at random from it too.

Learners (references are to Sutton and Barto, *Reinforcement Learning*, 2nd ed., 2018):

* :class:`QLearning` -- one-step Q-learning (Watkins 1989; S&B section 6.5).
* :class:`DynaQ` -- Dyna-Q (Sutton 1990; S&B section 8.2): Q-learning plus ``planning_steps``
  simulated updates per real step from a model that keeps, for each (s, a), the most recent
  outcome (r, s2) -- the same rule as the paper's world model (SPEC section 7: the most recent
  transition). Planning samples uniformly among the (s, a) met.
* :class:`DynaQPlus` -- Dyna-Q+ (Sutton 1990; S&B section 8.3), a model-based learner built for
  small discrete worlds: Dyna-Q whose planned backups add the exploration bonus
  ``kappa * sqrt(tau)`` to the modelled reward (tau: real steps since the pair was last tried),
  and whose model starts every untried action of a visited state as leading back to that state
  with reward 0 (S&B's footnote to the Dyna-Q+ example), so planning drives the robot to try it.
* :class:`PrioritizedSweeping` -- prioritized sweeping (Moore and Atkeson 1993), in the form for a
  deterministic model of S&B section 8.4 (Peng and Williams 1993 is the same idea): the same
  most-recent model as Dyna-Q; after each real step the (s, a) whose update would change Q by more
  than ``theta`` go into a priority queue keyed by that change, and up to ``planning_steps``
  updates are taken from its head, each queueing the predecessors of the state it changed.
  (Moore and Atkeson estimate transition probabilities; with the most-recent model each (s, a)
  has one successor, the deterministic case.)
"""

from __future__ import annotations

import dataclasses
import heapq
import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class LearnerConfig:
    """Hyper-parameters of a tabular learner (the tuned ones: ``TUNED`` below)."""

    alpha: float = 0.5  # step size
    gamma: float = 0.95  # discount
    epsilon: float = 0.05  # exploration: a uniformly random allowed action with this probability
    q_init: float = 0.0  # initial Q-value of every (s, a)
    planning_steps: int = 0  # Dyna-Q / prioritized sweeping: model updates per real step
    theta: float = 1e-4  # prioritized sweeping: smallest change queued
    kappa: float = 0.0  # Dyna-Q+: weight of the exploration bonus kappa sqrt(tau) in planning

    def __post_init__(self):
        if not 0 < self.alpha <= 1:
            raise ValueError(f"alpha must be in (0, 1], got {self.alpha!r}")
        if not 0 <= self.gamma < 1:
            raise ValueError(f"gamma must be in [0, 1) (a continuing task), got {self.gamma!r}")
        if not 0 <= self.epsilon <= 1:
            raise ValueError(f"epsilon must be a probability, got {self.epsilon!r}")
        if self.planning_steps < 0:
            raise ValueError(f"planning_steps must be >= 0, got {self.planning_steps!r}")
        if not self.theta >= 0:
            raise ValueError(f"theta must be >= 0, got {self.theta!r}")
        if not self.kappa >= 0:
            raise ValueError(f"kappa must be >= 0, got {self.kappa!r}")


class QLearning:
    """One-step tabular Q-learning over ``allowed`` actions per state (see module docstring)."""

    name = "q-learning"

    def __init__(self, allowed: list[list[int]], config: LearnerConfig, rng: np.random.Generator):
        if not isinstance(rng, np.random.Generator):
            raise TypeError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
        if not allowed or any(not acts for acts in allowed):
            raise ValueError("every state needs at least one allowed action")
        self.config = config
        self.rng = rng
        self.allowed = [list(acts) for acts in allowed]
        n_actions = 1 + max(max(acts) for acts in self.allowed)
        # Plain lists: the lifetime makes ~10^4-10^5 small updates, where NumPy scalars cost more.
        self.q = [[float(config.q_init)] * n_actions for _ in self.allowed]
        self.real_steps = 0
        self.updates = 0  # Q-value updates, real and planned

    # -- acting ----------------------------------------------------------------------------

    def greedy(self, s: int) -> int:
        """The allowed action of highest Q in s (ties broken at random)."""
        acts = self.allowed[s]
        if len(acts) == 1:
            return acts[0]
        row = self.q[s]
        best = max(row[a] for a in acts)
        ties = [a for a in acts if row[a] == best]
        return ties[0] if len(ties) == 1 else ties[int(self.rng.integers(len(ties)))]

    def act(self, s: int) -> int:
        acts = self.allowed[s]
        if len(acts) > 1 and self.config.epsilon and self.rng.random() < self.config.epsilon:
            return acts[int(self.rng.integers(len(acts)))]
        return self.greedy(s)

    def value(self, s: int) -> float:
        row = self.q[s]
        return max(row[a] for a in self.allowed[s])

    # -- learning ----------------------------------------------------------------------------

    def _backup(self, s: int, a: int, r: float, s2: int, done: bool) -> float:
        """One Q-learning update of (s, a) towards r + gamma max Q(s2) (r alone when done)."""
        cfg = self.config
        target = r if done else r + cfg.gamma * self.value(s2)
        delta = cfg.alpha * (target - self.q[s][a])
        self.q[s][a] += delta
        self.updates += 1
        return abs(delta)

    def observe(self, s: int, a: int, r: float, s2: int, done: bool = False) -> None:
        self.real_steps += 1
        self._backup(s, a, r, s2, done)

    def policy(self) -> list[int]:
        """The greedy action of every state (ties: the lowest action, no random draw)."""
        out = []
        for s, acts in enumerate(self.allowed):
            row = self.q[s]
            out.append(max(acts, key=lambda a: (row[a], -a)))
        return out


class DynaQ(QLearning):
    """Dyna-Q: Q-learning plus planning from a most-recent-outcome model (module docstring)."""

    name = "dyna-q"

    def __init__(self, allowed, config: LearnerConfig, rng: np.random.Generator):
        super().__init__(allowed, config, rng)
        # (s, a) -> its most recent outcome (r, s2, done)
        self.model: dict[tuple[int, int], tuple[float, int, bool]] = {}
        self._seen: list[tuple[int, int]] = []  # the keys of the model, for uniform sampling

    def _remember(self, s: int, a: int, r: float, s2: int, done: bool):
        old = self.model.get((s, a))
        if old is None:
            self._seen.append((s, a))
        self.model[(s, a)] = (r, s2, done)
        return old

    def observe(self, s: int, a: int, r: float, s2: int, done: bool = False) -> None:
        super().observe(s, a, r, s2, done)
        self._remember(s, a, r, s2, done)
        seen, model = self._seen, self.model
        n = len(seen)
        if not self.config.planning_steps:
            return
        for k in self.rng.integers(n, size=self.config.planning_steps).tolist():
            ps, pa = seen[k]
            self._backup(ps, pa, *model[(ps, pa)])


class DynaQPlus(DynaQ):
    """Dyna-Q+: Dyna-Q with an exploration bonus in planning and untried actions modelled as
    staying put with reward 0 (module docstring)."""

    name = "dyna-q+"

    def __init__(self, allowed, config: LearnerConfig, rng: np.random.Generator):
        super().__init__(allowed, config, rng)
        self.last_tried: dict[tuple[int, int], int] = {}  # (s, a) -> the real step it was last tried
        self._visited: set[int] = set()

    def observe(self, s: int, a: int, r: float, s2: int, done: bool = False) -> None:
        QLearning.observe(self, s, a, r, s2, done)
        if s not in self._visited:  # its untried actions enter the model, tried at step 0
            self._visited.add(s)
            for b in self.allowed[s]:
                if (s, b) not in self.model:
                    self._remember(s, b, 0.0, s, False)
        self._remember(s, a, r, s2, done)
        self.last_tried[(s, a)] = self.real_steps
        if not self.config.planning_steps:
            return
        seen, model, last, now = self._seen, self.model, self.last_tried, self.real_steps
        kappa = self.config.kappa
        for k in self.rng.integers(len(seen), size=self.config.planning_steps).tolist():
            ps, pa = seen[k]
            pr, ps2, pdone = model[(ps, pa)]
            self._backup(ps, pa, pr + kappa * math.sqrt(now - last.get((ps, pa), 0)), ps2, pdone)


class PrioritizedSweeping(DynaQ):
    """Prioritized sweeping with the most-recent model (module docstring)."""

    name = "prioritized-sweeping"

    def __init__(self, allowed, config: LearnerConfig, rng: np.random.Generator):
        super().__init__(allowed, config, rng)
        self.predecessors: dict[int, set[tuple[int, int]]] = {}  # s2 -> {(s, a) the model sends to s2}
        self._heap: list[tuple[float, int, int, int]] = []  # (-priority, order, s, a)
        self._queued: dict[tuple[int, int], float] = {}  # (s, a) -> its priority in the heap
        self._order = 0

    def _priority(self, s: int, a: int, r: float, s2: int, done: bool) -> float:
        target = r if done else r + self.config.gamma * self.value(s2)
        return abs(target - self.q[s][a])

    def _push(self, s: int, a: int, p: float) -> None:
        """Queue (s, a) with priority p (kept only if above theta and above its queued one)."""
        if p <= self.config.theta or p <= self._queued.get((s, a), 0.0):
            return
        self._queued[(s, a)] = p
        self._order += 1
        heapq.heappush(self._heap, (-p, self._order, s, a))

    def _pop(self) -> tuple[int, int] | None:
        heap, queued = self._heap, self._queued
        while heap:
            negp, _, s, a = heapq.heappop(heap)
            if queued.get((s, a)) == -negp:  # not a stale entry
                del queued[(s, a)]
                return s, a
        return None

    def observe(self, s: int, a: int, r: float, s2: int, done: bool = False) -> None:
        self.real_steps += 1
        old = self._remember(s, a, r, s2, done)
        if old is not None and old[1] != s2:
            self.predecessors[old[1]].discard((s, a))
        self.predecessors.setdefault(s2, set()).add((s, a))
        self._push(s, a, self._priority(s, a, r, s2, done))
        # The real step is learnt from through the queue (at its head when its change is the
        # largest); planning_steps 0 still takes that one update.
        for _ in range(max(1, self.config.planning_steps)):
            head = self._pop()
            if head is None:
                break
            ps, pa = head
            self._backup(ps, pa, *self.model[head])
            for qs, qa in self.predecessors.get(ps, ()):
                self._push(qs, qa, self._priority(qs, qa, *self.model[(qs, qa)]))


LEARNERS = {cls.name: cls for cls in (QLearning, DynaQ, DynaQPlus, PrioritizedSweeping)}


# Untuned starting points (S&B's examples use alpha 0.1-0.5, epsilon 0.1, n 5-50).
DEFAULTS = {
    "q-learning": LearnerConfig(alpha=0.5, gamma=0.95, epsilon=0.05),
    "dyna-q": LearnerConfig(alpha=0.5, gamma=0.95, epsilon=0.05, planning_steps=10),
    "dyna-q+": LearnerConfig(alpha=0.5, gamma=0.95, epsilon=0.05, planning_steps=10, kappa=1e-3),
    "prioritized-sweeping": LearnerConfig(alpha=0.5, gamma=0.95, epsilon=0.05, planning_steps=10),
}
# The seeds `ehw tune` chose the tabular (and deep) peers' settings on; `ehw compare` says whether
# the seeds it reports meet them.
TUNING_SEEDS = (1001, 1002, 1003, 1004, 1005)


def _tuned(method: str, **params) -> LearnerConfig:
    """A study's best trial, exactly as `ehw tune` ran it: its parameters over ``DEFAULTS``."""
    return dataclasses.replace(DEFAULTS[method], **params)


# (method, shaping) -> the best trial of `ehw tune METHOD --shaping SHAPING --trials 20` on
# TUNING_SEEDS (TPE seed 0; results/tune/<method>-<shaping>.json; docs/peers.md), never on the
# seeds `make compare` reports. Medians of the interactions to 64 targets over the tuning seeds.
TUNED: dict[tuple[str, str], LearnerConfig] = {
    # median 9,194 (trial 15; the earlier settings: 20,644)
    ("q-learning", "shaped"): _tuned("q-learning", alpha=0.08393163275518453, gamma=0.9251730990396935, epsilon=0.11870793414558267, q_init=1.8545287196039628),
    # median 21,131 (trial 0; the earlier settings: 21,131)
    ("q-learning", "unshaped"): _tuned("q-learning", alpha=0.5, gamma=0.97, epsilon=0.02, q_init=0.0),
    # median 12,961 (trial 17; the earlier settings: 23,852)
    ("dyna-q", "shaped"): _tuned("dyna-q", alpha=0.0587555248888176, gamma=0.9652845989059061, epsilon=0.06730228350981604, q_init=0.5575418591027931, planning_steps=2),
    # median 34,870 (trial 16; the earlier settings: 40,697)
    ("dyna-q", "unshaped"): _tuned("dyna-q", alpha=0.388683208026723, gamma=0.956291184077334, epsilon=0.006334227423233192, q_init=0.7992237778280907, planning_steps=8),
    # median 11,043 (trial 12; the earlier settings: 20,941)
    ("dyna-q+", "shaped"): _tuned("dyna-q+", alpha=0.3229952995283691, gamma=0.9082205546264067, epsilon=0.00837852272389397, q_init=1.2419155168951386, planning_steps=1, kappa=0.0007396831499457961),
    # median 34,917 (trial 17; the earlier settings: 48,459)
    ("dyna-q+", "unshaped"): _tuned("dyna-q+", alpha=0.5272368572976932, gamma=0.9084355147724624, epsilon=0.0014268965957304086, q_init=0.8094304342464463, planning_steps=1, kappa=0.00022217655718736733),
    # median 17,490 (trial 10; the earlier settings: 24,791)
    ("prioritized-sweeping", "shaped"): _tuned("prioritized-sweeping", alpha=0.29020947579610423, gamma=0.8568084852176229, epsilon=0.003953771783246918, q_init=0.03322762793822717, planning_steps=16),
    # median 27,056 (trial 10; the earlier settings: 31,307)
    ("prioritized-sweeping", "unshaped"): _tuned("prioritized-sweeping", alpha=0.29020947579610423, gamma=0.8568084852176229, epsilon=0.003953771783246918, q_init=0.03322762793822717, planning_steps=16),
}


def tuned_config(method: str, shaping: str) -> LearnerConfig:
    return TUNED.get((method, shaping), DEFAULTS[method])


def make_learner(method: str, allowed, config: LearnerConfig, rng: np.random.Generator):
    if method not in LEARNERS:
        raise ValueError(f"tabular learner must be one of {sorted(LEARNERS)}, got {method!r}")
    return LEARNERS[method](allowed, config, rng)

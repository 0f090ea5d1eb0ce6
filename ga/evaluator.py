"""Model-based fitness of SPEC section 7 (normative): (crashes, loops, distance) and the fitness.

Two implementations that must agree exactly:

- :func:`evaluate_python` / :func:`trace_counts`: the SPEC pseudo-code, line by line (one genome).
- :func:`evaluate_population`: a whole population at once in NumPy, no Python loop per state or
  per individual. It uses three facts that follow from the pseudo-code (and the world-model
  invariant that every next state is in S):

  1. every state of S is tested exactly once (a trace only moves to an untested state), so
     ``crashes`` = #{s in S : model[s, T(s)] is a crash} and ``distance`` = the sum of
     dist[T(s)] over the s in S whose entry is known and not a crash (T = the truth table);
  2. a trace stops in s unless s is *continuing*: its entry is known, not a crash, and not the
     free-space self-loop (next = s with no obstacle bit). Continuing states form a functional
     graph s -> next(s);
  3. ``loops`` = the number of cycles of that graph: the first trace that enters a cycle walks
     round it (every node continues) and closes it (s2 in trace), and a later trace stops on a
     tested node before closing it again. A self-loop with obstacle bits is a cycle of length 1.

  Cycles are counted by pointer doubling, for the whole population at once, on the graph of the
  continuing (individual, state) pairs plus one shared sink (a continuing state whose successor
  does not continue points to the sink). After ceil(log2(N + 1)) squarings f^L (L >= N + 1) maps
  every node onto its cycle, so the image of f^L is the set of cyclic nodes; a cyclic node is
  counted when it is the smallest node of its cycle (the running minimum over L steps). The only
  Python loop is over those ~log2(N) rounds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ga.fail_rates import RATE_ONE, W_FAIL, fail_counts
from ga.genome import validate_rows
from ga.motions import (DEFAULT_DISTANCE_RULE, MAX_MOTION_DISTANCE_MM, N_MOTIONS, N_STATES, OBSTACLE_MASK,
                        motion_distances)
from ga.truth_table import motion_of, truth_tables
from ga.world_model import WorldModel

# Fitness weights of SPEC section 7.
W_CRASHES, W_LOOPS, W_DISTANCE = 0.5, 0.4, 0.1


@dataclass(frozen=True)
class EvalResult:
    """(crashes, loops, distance) of each controller, and ``fails``, the failure-rate count F of
    ``ga.fail_rates`` (zeros when the evaluation had no rate codes): int64 arrays (P,)."""

    crashes: np.ndarray
    loops: np.ndarray
    distance: np.ndarray
    fails: np.ndarray | None = None

    def __post_init__(self):
        if self.fails is None:
            object.__setattr__(self, "fails", np.zeros(np.shape(self.crashes), dtype=np.int64))

    def __len__(self) -> int:
        return len(self.crashes)

    def row(self, i: int) -> tuple[int, int, int]:
        return int(self.crashes[i]), int(self.loops[i]), int(self.distance[i])


def fitness(result: EvalResult, n_states: int) -> np.ndarray:
    """Fitness of SPEC section 7 for every controller: (P,) float64.

    fitness = 0.5 (1 - crashes/N) + 0.4 (1 - loops/N) + 0.1 distance / (N max(dist)),
    less W_FAIL fails / (N RATE_ONE), the failure rates' term (``ga.fail_rates``; 0 without codes).
    With N = 0 (an empty model) every controller is equally unknown: the fitness is 0.
    """
    if isinstance(n_states, bool) or not isinstance(n_states, (int, np.integer)) or n_states < 0:
        raise ValueError(f"n_states must be a non-negative integer, got {n_states!r}")
    crashes = np.asarray(result.crashes, dtype=np.float64)
    if n_states == 0:
        return np.zeros(crashes.shape, dtype=np.float64)
    n = float(n_states)
    loops = np.asarray(result.loops, dtype=np.float64)
    distance = np.asarray(result.distance, dtype=np.float64)
    fails = np.asarray(result.fails, dtype=np.float64)
    return (W_CRASHES * (1.0 - crashes / n) + W_LOOPS * (1.0 - loops / n)
            + W_DISTANCE * distance / (n * MAX_MOTION_DISTANCE_MM) - W_FAIL * fails / (n * RATE_ONE))


# -- the pseudo-code, one genome ------------------------------------------------------------------


def trace_counts(motion, model: WorldModel, distance_rule: str = DEFAULT_DISTANCE_RULE) -> tuple[int, int, int]:
    """The SPEC pseudo-code for one controller given as ``motion(state) -> code`` (a callable,
    or a 256-entry truth table). Returns (crashes, loops, distance). ``distance_rule``: dist[a],
    ``ga.motions.DISTANCE_RULES`` ("forward" is the SPEC)."""
    if not callable(motion):
        table = [int(v) for v in np.asarray(motion).reshape(-1)]
        if len(table) != N_STATES:
            raise ValueError(f"a truth table has {N_STATES} entries, got {len(table)}")
        motion = table.__getitem__
    valid, crash, nxt = model.valid.tolist(), model.crash.tolist(), model.next_state.tolist()
    dist = [int(d) for d in motion_distances(distance_rule)]
    tested: set[int] = set()
    crashes = loops = distance = 0
    for s0 in model.states.tolist():
        if s0 in tested:
            continue
        trace: set[int] = set()
        s = s0
        while True:
            tested.add(s)
            trace.add(s)
            a = motion(s)
            if not valid[s][a]:  # (i) unknown transition
                break
            if crash[s][a]:  # (ii) crash
                crashes += 1
                break
            distance += dist[a]
            s2 = nxt[s][a]
            if s2 == s and not s & OBSTACLE_MASK:  # progress in free space, not a loop
                break
            if s2 in trace:  # (iv) infinite loop
                loops += 1
                break
            if s2 in tested:  # (iii) already tested
                break
            s = s2
    return crashes, loops, distance


def evaluate_python(rows, model: WorldModel, reflex: bool = True,
                    distance_rule: str = DEFAULT_DISTANCE_RULE) -> tuple[int, int, int]:
    """(crashes, loops, distance) of one genome (50,) by the plain pseudo-code, the motion of each
    visited state computed by the plain row-by-row evaluation ``ga.truth_table.motion_of``."""
    rows = validate_rows(rows)
    if rows.ndim != 1:
        raise ValueError(f"evaluate_python takes one genome of shape (50,), got {rows.shape!r}")
    return trace_counts(lambda s: motion_of(rows, s, reflex), model, distance_rule)


# -- the vectorised population evaluator ----------------------------------------------------------


def evaluate_tables(tables, model: WorldModel, distance_rule: str = DEFAULT_DISTANCE_RULE,
                    rates=None) -> EvalResult:
    """(crashes, loops, distance) for truth tables (P, 256) (or (256,)): see the module docstring.
    ``distance_rule``: dist[a], ``ga.motions.DISTANCE_RULES`` ("forward" is the SPEC). ``rates``:
    the failure-rate codes (256, 8) of ``ga.fail_rates``, for ``fails``; None: fails are 0."""
    tables = np.asarray(tables)
    if tables.ndim == 1:
        tables = tables[None]
    result = _trace_tables(tables, model, distance_rule)
    if rates is None:
        return result
    return EvalResult(result.crashes, result.loops, result.distance, fail_counts(tables, model.states, rates))


def _trace_tables(tables: np.ndarray, model: WorldModel, distance_rule: str) -> EvalResult:
    dist = motion_distances(distance_rule)
    if tables.ndim != 2 or tables.shape[1] != N_STATES:
        raise ValueError(f"truth tables must have shape (P, {N_STATES}), got {tables.shape!r}")
    pop = tables.shape[0]
    states = model.states  # S ascending, (N,)
    n = len(states)
    if n == 0 or pop == 0:
        zeros = np.zeros(pop, dtype=np.int64)
        return EvalResult(zeros, zeros.copy(), zeros.copy())
    # Per-entry tables of this model (256 x 8, cheap), then one flat index per (individual, state).
    index_of = np.full(N_STATES, n, dtype=np.intp)  # position in S; n = the sink
    index_of[states] = np.arange(n)
    moves = model.valid & ~model.crash  # the pseudo-code gets past (i) and (ii)
    free_self = (model.next_state == np.arange(N_STATES)[:, None]) & (
        (np.arange(N_STATES) & OBSTACLE_MASK) == 0)[:, None]
    # Packed per entry: successor position (bits 0-8), crash (bit 9), distance covered (10 and up).
    successor = np.where(moves & ~free_self, index_of[model.next_state], n)
    step_distance = np.where(moves, dist[None, :], 0)
    packed = (successor | (model.crash.astype(np.intp) << 9) | (step_distance << 10)).ravel()
    flat = states[None, :] * N_MOTIONS + np.take(tables, states, axis=1)  # (P, N) entry per state
    entry = np.take(packed, flat)
    crashes = ((entry >> 9) & 1).sum(axis=1, dtype=np.int64)
    distance = (entry >> 10).sum(axis=1, dtype=np.int64)
    # (P, N): position in S of the successor, or n (the sink). The node arrays below are int32
    # when P N fits (always, for populations below 8 million): half the gathers' memory traffic.
    idx = np.int32 if pop * (n + 1) < 2**31 else np.intp
    succ_local = (entry & 0x1FF).astype(idx)

    # Functional graph of the continuing states of every individual at once: node ids 0..C-1 for
    # the C continuing (individual, state) pairs, C for one shared sink. A continuing state whose
    # successor does not continue points to the sink (a trace stops there: no cycle through it).
    succ_flat = succ_local.ravel()
    continuing = succ_flat != n
    count = int(continuing.sum())
    if count == 0:
        return EvalResult(crashes, np.zeros(pop, dtype=np.int64), distance)
    node_of = np.cumsum(continuing, dtype=idx) - 1  # flat position p N + i -> node id (where continuing)
    owner = np.repeat(np.arange(pop, dtype=idx), n)[continuing]  # individual of each node
    target = owner * idx(n) + succ_flat[continuing]  # flat position of each node's successor
    succ = np.empty(count + 1, dtype=idx)
    succ[:count] = np.where(np.take(continuing, target), np.take(node_of, target), count)
    succ[count] = count
    node = np.arange(count + 1, dtype=idx)
    low = node.copy()  # the smallest node id on the path window (a cycle stays in one individual)
    rounds = int(np.ceil(np.log2(n + 1)))
    for _ in range(rounds):  # window doubles: 1, 2, 4, ... >= N + 1 steps
        np.minimum(low, np.take(low, succ), out=low)
        succ = np.take(succ, succ)
    # succ = f^L with L >= N + 1: every node now sits on its cycle (or at the sink).
    cyclic = np.zeros(count + 1, dtype=bool)
    cyclic[succ] = True
    heads = cyclic[:count] & (low[:count] == node[:count])
    loops = np.bincount(owner[heads], minlength=pop).astype(np.int64)
    return EvalResult(crashes, loops, distance)


def evaluate_population(rows, model: WorldModel, reflex: bool = True,
                        distance_rule: str = DEFAULT_DISTANCE_RULE, rates=None) -> EvalResult:
    """(crashes, loops, distance) of every genome of ``rows`` (P, 50) (or one genome (50,)) on
    ``model``, and fails with ``rates`` (``evaluate_tables``); int64 arrays (P,). Bit-exact with
    :func:`evaluate_python`."""
    rows = validate_rows(rows)
    tables = truth_tables(rows[None] if rows.ndim == 1 else rows, reflex)
    return evaluate_tables(tables, model, distance_rule, rates)

"""The world model of the on-line model-based method: SPEC section 7 (normative update rule).

The robot learns a transition table indexed by (world state, motion). Each entry holds whether it
is known (``valid``), whether the motion crashed (``crash``) and the observed ``next_state``.

Update rule (normative): a new observation overwrites the entry with the most recent outcome,
except that an entry recording a crash is never overwritten. The state set S holds every state
the robot has been in: the from-state and the next state of every observation, plus the initial
state (:meth:`WorldModel.visit`).

Crash entries: on a crash the robot is put back where it was before the motion (SPEC section 4),
so a crash entry records ``next_state = state``. The evaluator never follows a crash entry's next
state, so this choice changes no fitness; it keeps the invariant "every next state in the table is
in S" trivially true. The state the robot observes after being put back is still added to S (the
robot has been in it).

Invariant kept by every method (and checked by :meth:`WorldModel.load`): the from-state and the
next state of every valid entry are in S. The vectorised evaluator (``ga.evaluator``) relies on it.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from ga.motions import N_MOTIONS, N_STATES

FORMAT_TAG = "ehw-world-model"
FORMAT_VERSION = 1


class WorldModelError(ValueError):
    """A bad observation, or a world-model file that is corrupt or of another format/version."""


def _check_state(name: str, value) -> int:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise WorldModelError(f"{name} must be an integer world state in 0..{N_STATES - 1}, got {value!r}")
    if not 0 <= int(value) < N_STATES:
        raise WorldModelError(f"{name} must be a world state in 0..{N_STATES - 1}, got {value!r}")
    return int(value)


def _check_motion(value) -> int:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise WorldModelError(f"motion must be an integer code in 0..{N_MOTIONS - 1}, got {value!r}")
    if not 0 <= int(value) < N_MOTIONS:
        raise WorldModelError(f"motion must be a code in 0..{N_MOTIONS - 1}, got {value!r}")
    return int(value)


class WorldModel:
    """Transition table (256 states x 8 motions) and state set S of SPEC section 7.

    Attributes
    ----------
    valid : bool (256, 8)
        The entry (state, motion) has been observed.
    crash : bool (256, 8)
        The observed motion crashed (a crash entry is permanent).
    next_state : uint8 (256, 8)
        The observed next state (``state`` itself for a crash entry; 0 where not valid).
    in_set : bool (256,)
        Membership of the state set S.
    """

    def __init__(self):
        self.valid = np.zeros((N_STATES, N_MOTIONS), dtype=bool)
        self.crash = np.zeros((N_STATES, N_MOTIONS), dtype=bool)
        self.next_state = np.zeros((N_STATES, N_MOTIONS), dtype=np.uint8)
        self.in_set = np.zeros(N_STATES, dtype=bool)

    # -- updates ---------------------------------------------------------------------------------

    def visit(self, state: int) -> bool:
        """Add ``state`` to S (e.g. the initial state). True when S grew."""
        state = _check_state("state", state)
        grew = not self.in_set[state]
        self.in_set[state] = True
        return grew

    def observe(self, state: int, motion: int, next_state: int, crashed: bool) -> bool:
        """Record one interaction: ``motion`` taken in ``state`` led to ``next_state``.

        ``crashed``: the bumper touched something; the robot was put back, and ``next_state`` is
        what it observes then. Applies the normative rule (most recent outcome wins, a crash entry
        is never overwritten), adds both states to S. Returns True when the model changed (the
        entry or the state set), False when it already said exactly this (or kept its crash).
        """
        state = _check_state("state", state)
        motion = _check_motion(motion)
        next_state = _check_state("next_state", next_state)
        crashed = bool(crashed)
        grew = self.visit(state)
        grew = self.visit(next_state) or grew
        if self.crash[state, motion]:
            return grew  # a crash entry is never overwritten
        stored_next = state if crashed else next_state
        if self.valid[state, motion] and self.crash[state, motion] == crashed \
                and self.next_state[state, motion] == stored_next:
            return grew
        self.valid[state, motion] = True
        self.crash[state, motion] = crashed
        self.next_state[state, motion] = stored_next
        return True

    # -- queries ---------------------------------------------------------------------------------

    @property
    def states(self) -> np.ndarray:
        """The state set S, ascending: int64 array."""
        return np.flatnonzero(self.in_set)

    @property
    def n_states(self) -> int:
        """N = |S|."""
        return int(self.in_set.sum())

    @property
    def n_transitions(self) -> int:
        """Number of known (state, motion) entries, crashes included."""
        return int(self.valid.sum())

    @property
    def n_crashes(self) -> int:
        """Number of crash entries."""
        return int(self.crash.sum())

    def entries(self) -> np.ndarray:
        """Every valid entry as rows (state, motion, next_state, crash), ascending by (state,
        motion): int64 (T, 4). The order in which a host writes them to the evaluator board."""
        s, a = np.nonzero(self.valid)
        return np.stack([s, a, self.next_state[s, a], self.crash[s, a]], axis=1).astype(np.int64)

    def copy(self) -> "WorldModel":
        other = WorldModel()
        other.valid[...] = self.valid
        other.crash[...] = self.crash
        other.next_state[...] = self.next_state
        other.in_set[...] = self.in_set
        return other

    def __eq__(self, other) -> bool:
        if not isinstance(other, WorldModel):
            return NotImplemented
        return (np.array_equal(self.valid, other.valid) and np.array_equal(self.crash, other.crash)
                and np.array_equal(self.next_state, other.next_state)
                and np.array_equal(self.in_set, other.in_set))

    __hash__ = None

    def __repr__(self) -> str:
        return f"WorldModel(n_states={self.n_states}, n_transitions={self.n_transitions}, n_crashes={self.n_crashes})"

    # -- files -----------------------------------------------------------------------------------

    def to_dict(self) -> dict:
        """A JSON-able description: format tag, version, S and the valid entries."""
        return {
            "format": FORMAT_TAG,
            "version": FORMAT_VERSION,
            "states": [int(s) for s in self.states],
            "transitions": [[int(v) for v in row] for row in self.entries()],
        }

    @classmethod
    def from_dict(cls, data) -> "WorldModel":
        """Inverse of :meth:`to_dict`; any inconsistency raises :class:`WorldModelError`."""
        if not isinstance(data, dict):
            raise WorldModelError(f"a world model is a JSON object, got {type(data).__name__!r}")
        if data.get("format") != FORMAT_TAG:
            raise WorldModelError(f"not a world-model file: format tag {data.get('format')!r}, expected {FORMAT_TAG!r}")
        if data.get("version") != FORMAT_VERSION:
            raise WorldModelError(f"unsupported world-model version {data.get('version')!r}, expected {FORMAT_VERSION!r}")
        states, transitions = data.get("states"), data.get("transitions")
        if not isinstance(states, list) or not isinstance(transitions, list):
            raise WorldModelError("a world model needs the lists 'states' and 'transitions'")
        model = cls()
        for s in states:
            if model.in_set[_check_state("a state of S", s)]:
                raise WorldModelError(f"state {s!r} is listed twice in S")
            model.in_set[s] = True
        for entry in transitions:
            if not isinstance(entry, list) or len(entry) != 4:
                raise WorldModelError(f"a transition is [state, motion, next_state, crash], got {entry!r}")
            s, a, nxt, crash = entry
            s, a = _check_state("state", s), _check_motion(a)
            nxt = _check_state("next_state", nxt)
            if crash not in (0, 1) or isinstance(crash, float):
                raise WorldModelError(f"crash flag must be 0 or 1, got {crash!r} in {entry!r}")
            if model.valid[s, a]:
                raise WorldModelError(f"transition ({s}, {a}) is listed twice")
            if not (model.in_set[s] and model.in_set[nxt]):
                raise WorldModelError(f"transition {entry!r} names a state outside S")
            if crash and nxt != s:
                raise WorldModelError(f"a crash entry records next_state = state, got {entry!r}")
            model.valid[s, a], model.crash[s, a], model.next_state[s, a] = True, bool(crash), nxt
        return model

    def save(self, path: os.PathLike | str) -> Path:
        """Write the model as JSON (atomically: a temporary file then a rename)."""
        path = Path(path)
        tmp = path.with_name(path.name + ".tmp")
        tmp.write_text(json.dumps(self.to_dict()) + "\n")
        tmp.replace(path)
        return path

    @classmethod
    def load(cls, path: os.PathLike | str) -> "WorldModel":
        """Read a file written by :meth:`save`; a corrupt or mismatched file raises WorldModelError."""
        path = Path(path)
        try:
            data = json.loads(path.read_text())
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise WorldModelError(f"cannot read world model {str(path)!r}: {exc}") from exc
        try:
            return cls.from_dict(data)
        except WorldModelError as exc:
            raise WorldModelError(f"{str(path)!r}: {exc}") from exc

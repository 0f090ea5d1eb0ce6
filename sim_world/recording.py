"""What a replay of a robot's path needs, in one compact file: ``lifetime.npz`` in the run folder.

The on-line lifetime loop (``cosim.online.run.OnlineRun.step``) keeps, per interaction, the pose
(x, y, heading), the state sensed there and the event (crash, target, relocation) in
``run.trajectory``, and the curves of the world model's growth; the learning phases (each ending
in a download) are ``run.phases``; ``cosim.online.report.recording_of`` packs them. The off-line
method records the path of its best controller (``cosim.offline.report.plot_results``). This
module defines the file: NumPy arrays (float32 poses, integer codes), no pickled objects. A
resumed on-line run rebuilds ``run.trajectory`` by replaying the checkpoint's motions through the
same world (``OnlineRun.load_state``), so it writes the same recording as an uninterrupted one.

Arrays (N trajectory entries: the start, one per interaction, one more per relocation; P phases):

- ``pose`` (N, 3) float32: x, y in mm, heading in rad; ``state`` (N,) uint8: the 8 sensor bits
  sensed at that pose; ``event`` (N,) uint8: an index into ``EVENTS``; ``interaction`` (N,)
  int32: the interactions done when the pose was reached;
- ``motions`` (I,) uint8; ``curve_states``, ``curve_transitions`` (I,) int32: |S| and the world
  model's entries after each interaction;
- ``phase_interaction`` (P,) int32, ``phase_reason`` (P,) str, ``phase_changed`` (P,) bool:
  when each learning phase ran, why, and whether the downloaded controller changed the motion
  of the failing state;
- ``transitions`` (K, 4) uint8: every distinct (state, motion, next state, crashed) observed;
- ``arena`` () str, ``seed`` () int64, ``method`` () str.
"""

from __future__ import annotations

import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from base.files import atomic_write_bytes

RECORDING = "lifetime.npz"
EVENTS = ("", "start", "crash", "target", "relocate")
_EVENT_CODE = {name: i for i, name in enumerate(EVENTS)}


@dataclass(frozen=True)
class Recording:
    """A lifetime's recording (the arrays of the module docstring)."""

    pose: np.ndarray
    state: np.ndarray
    event: np.ndarray
    interaction: np.ndarray
    motions: np.ndarray
    curve_states: np.ndarray
    curve_transitions: np.ndarray
    phase_interaction: np.ndarray
    phase_reason: np.ndarray
    phase_changed: np.ndarray
    transitions: np.ndarray
    arena: str
    seed: int
    method: str

    @property
    def has_states(self) -> bool:
        """False where the recorder did not know the sensed states (all 255: sense them again)."""
        return not bool(np.all(self.state == 255)) if self.state.size else False

    def events(self, name: str) -> np.ndarray:
        """The indices of the trajectory entries with event ``name``."""
        return np.flatnonzero(self.event == _EVENT_CODE[name])


def trajectory_arrays(trajectory) -> dict:
    """Pose, state, event and interaction arrays of a trajectory of (x, y, heading, state, event)
    entries; a (x, y, heading, event) entry (the off-line recorder's) gets state 255, unknown."""
    n = len(trajectory)
    pose = np.zeros((n, 3), dtype=np.float32)
    state = np.full(n, 255, dtype=np.uint8)
    event = np.zeros(n, dtype=np.uint8)
    for i, entry in enumerate(trajectory):
        pose[i] = entry[:3]
        if len(entry) == 5:
            state[i] = entry[3]
        event[i] = _EVENT_CODE[entry[-1]]
    # An interaction is every entry but the start and the relocation after a target.
    steps = (event != _EVENT_CODE["start"]) & (event != _EVENT_CODE["relocate"])
    return {"pose": pose, "state": state, "event": event,
            "interaction": np.cumsum(steps, dtype=np.int32)}


def write_recording(arrays: dict, out: Path) -> Path:
    """Write ``arrays`` (``recording_of``, or a trajectory's with the keys of ``Recording``) to
    ``out/lifetime.npz`` atomically; missing curves and phases are written empty."""
    empty = {"motions": np.zeros(0, np.uint8), "curve_states": np.zeros(0, np.int32),
             "curve_transitions": np.zeros(0, np.int32), "phase_interaction": np.zeros(0, np.int32),
             "phase_reason": np.zeros(0, "U8"), "phase_changed": np.zeros(0, bool),
             "transitions": np.zeros((0, 4), np.uint8)}
    buffer = io.BytesIO()
    np.savez_compressed(buffer, **{**empty, **arrays})
    path = Path(out) / RECORDING
    atomic_write_bytes(path, buffer.getvalue())
    return path


def load_recording(path: Path) -> Recording:
    """The recording in ``path`` (a ``lifetime.npz``, or the run folder holding it)."""
    path = Path(path)
    if path.is_dir():
        path = path / RECORDING
    with np.load(path, allow_pickle=False) as data:
        fields = {name: data[name] for name in Recording.__dataclass_fields__}
    for name in ("arena", "method"):
        fields[name] = str(fields[name])
    fields["seed"] = int(fields["seed"])
    return Recording(**fields)

"""Atomic JSON checkpoints for long experiment runs (off-line and on-line runners).

A checkpoint file is one JSON object::

    {"format": 1, "kind": "<runner name>", "config": {...}, "state": {...}}

``config`` holds the parameters that define the run (seed, population, arena, ...): a run may only
be resumed under the same config, otherwise the resumed run would not be the run that was
interrupted. ``state`` is whatever the runner needs to continue (GA state, counters, history).

Writes are atomic: the JSON goes to a temporary file in the same directory, is flushed and
fsync'ed, then `os.replace` swaps it in, so a run killed mid-write leaves the previous checkpoint
intact.
"""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path

CHECKPOINT_FORMAT = 1


class CheckpointError(RuntimeError):
    """A checkpoint that cannot be used: missing, corrupt, of another kind, format or config."""


def save_checkpoint(path, kind: str, config: dict, state: dict) -> None:
    """Write ``state`` atomically to ``path`` (parent directories are created)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    payload = {"format": CHECKPOINT_FORMAT, "kind": kind, "config": config, "state": state}
    text = json.dumps(payload, sort_keys=True, allow_nan=False)
    fd, tmp = tempfile.mkstemp(prefix=path.name + ".", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise


def _normalise(config: dict) -> dict:
    """The config as it reads back from JSON (tuples become lists, keys become strings)."""
    return json.loads(json.dumps(config, sort_keys=True))


def load_checkpoint(path, kind: str, config: dict) -> dict:
    """The ``state`` saved at ``path``, after checking kind, format and config.

    Raises CheckpointError naming the problem: a missing or unreadable file, invalid JSON, a
    missing field, another kind, another format version, or a config that differs (the
    differing keys with both values).
    """
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise CheckpointError(f"cannot read checkpoint {str(path)!r}: {exc}") from exc
    try:
        payload = json.loads(text)
    except json.JSONDecodeError as exc:
        raise CheckpointError(f"checkpoint {str(path)!r} is corrupt (not valid JSON: {exc})") from exc
    if not isinstance(payload, dict) or not {"format", "kind", "config", "state"} <= payload.keys():
        raise CheckpointError(
            f"checkpoint {str(path)!r} is corrupt (expected an object with format, kind, config, state)"
        )
    if payload["format"] != CHECKPOINT_FORMAT:
        raise CheckpointError(
            f"checkpoint {str(path)!r} has format version {payload['format']!r}, "
            f"this code reads version {CHECKPOINT_FORMAT}"
        )
    if payload["kind"] != kind:
        raise CheckpointError(f"checkpoint {str(path)!r} is a {payload['kind']!r} checkpoint, not {kind!r}")
    saved, wanted = payload["config"], _normalise(config)
    if saved != wanted:
        keys = sorted(set(saved) | set(wanted))
        diffs = [
            f"{k}: saved {saved.get(k, '<absent>')!r}, now {wanted.get(k, '<absent>')!r}"
            for k in keys
            if saved.get(k, object()) != wanted.get(k, object())
        ]
        raise CheckpointError(
            f"checkpoint {str(path)!r} was made with another config; differing keys: " + "; ".join(diffs)
        )
    if not isinstance(payload["state"], dict):
        raise CheckpointError(f"checkpoint {str(path)!r} is corrupt (state is not an object)")
    return payload["state"]

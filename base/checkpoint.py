"""Atomic, checksummed JSON checkpoints for long experiment runs (off-line and on-line runners).

A checkpoint file is one JSON object::

    {"format": 2, "kind": "<runner name>", "config": {...}, "state": {...}, "sha256": "<hex>"}

``config`` holds the parameters that define the run (seed, population, arena, ...): a run may only
be resumed under the same config, otherwise the resumed run would not be the run that was
interrupted (:func:`read_checkpoint` gives the stored config, for a resume that uses it).
``state`` is whatever the runner needs to continue (GA state, counters, history). ``sha256`` is
the SHA-256 of the canonical JSON of the other four fields: a hand-edited or bit-flipped file is
refused, never resumed with the edited values.

Writes are atomic (``base.files.atomic_write_text``): the JSON goes to a temporary file in the same
directory, is flushed and fsync'ed, then `os.replace` swaps it in, so a run killed mid-write
leaves the previous checkpoint intact.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

from base.errors import UserError
from base.files import atomic_write_text

CHECKPOINT_FORMAT = 2  # 2: with the sha256 field


class CheckpointError(UserError, RuntimeError):
    """A checkpoint that cannot be used: missing, corrupt, edited, of another kind, format or config."""


def _canonical(payload: dict) -> str:
    return json.dumps(payload, sort_keys=True, allow_nan=False, separators=(",", ":"))


def _digest(payload: dict) -> str:
    body = {k: payload[k] for k in ("format", "kind", "config", "state")}
    return hashlib.sha256(_canonical(body).encode()).hexdigest()


def save_checkpoint(path, kind: str, config: dict, state: dict) -> None:
    """Write ``state`` atomically to ``path`` (parent directories are created)."""
    # Through JSON first, so the checksum is over what a reader gets back (tuples -> lists).
    payload = json.loads(_canonical({"format": CHECKPOINT_FORMAT, "kind": kind, "config": config,
                                     "state": state}))
    payload["sha256"] = _digest(payload)
    atomic_write_text(Path(path), json.dumps(payload, sort_keys=True, allow_nan=False))


def _normalise(config: dict) -> dict:
    """The config as it reads back from JSON (tuples become lists, keys become strings)."""
    return json.loads(json.dumps(config, sort_keys=True))


def read_checkpoint(path, kind: str) -> tuple[dict, dict]:
    """``(config, state)`` stored at ``path``, after checking format, kind and checksum.

    Raises CheckpointError naming the problem: a missing or unreadable file, invalid JSON, a
    missing field, another format version, another kind, or a checksum that does not match
    (the file was edited or damaged).
    """
    path = Path(path)
    name = repr(str(path))
    try:
        text = path.read_bytes().decode()
    except OSError as exc:
        raise CheckpointError(f"cannot read checkpoint {name}: {exc.strerror or exc}") from None
    except UnicodeDecodeError:
        raise CheckpointError(f"checkpoint {name} is corrupt (not UTF-8 text)") from None
    try:
        payload = json.loads(text)
    except (ValueError, RecursionError) as exc:
        raise CheckpointError(f"checkpoint {name} is corrupt (not valid JSON: {exc})") from None
    if not isinstance(payload, dict) or not {"format", "kind", "config", "state"} <= payload.keys():
        raise CheckpointError(
            f"checkpoint {name} is corrupt (expected an object with format, kind, config, state)")
    if payload["format"] != CHECKPOINT_FORMAT:
        raise CheckpointError(
            f"checkpoint {name} has format version {payload['format']!r}, this code reads version "
            f"{CHECKPOINT_FORMAT}")
    if payload["kind"] != kind:
        raise CheckpointError(f"checkpoint {name} is a {payload['kind']!r} checkpoint, not {kind!r}")
    try:
        digest = _digest(payload)
    except (ValueError, TypeError):  # NaN/Infinity literals: never written by save_checkpoint
        digest = None
    if payload.get("sha256") != digest:
        raise CheckpointError(
            f"checkpoint {name} fails its checksum (sha256): it was edited or damaged; a run "
            "resumes only from the file it wrote")
    if not isinstance(payload["config"], dict):
        raise CheckpointError(f"checkpoint {name} is corrupt (config is not an object)")
    if not isinstance(payload["state"], dict):
        raise CheckpointError(f"checkpoint {name} is corrupt (state is not an object)")
    return payload["config"], payload["state"]


def load_checkpoint(path, kind: str, config: dict) -> dict:
    """The ``state`` saved at ``path``, after :func:`read_checkpoint`'s checks and a check that
    the stored config is ``config`` (else the differing keys with both values)."""
    saved, state = read_checkpoint(path, kind)
    wanted = _normalise(config)
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
    return state

"""Result files that are whole or absent: atomic writes and merged JSON files.

- **Atomic writes.** :func:`atomic_write_text` / :func:`atomic_savefig` write a temporary file in
  the same folder, fsync it and ``os.replace`` it in: a run killed mid-write leaves the previous
  file whole, never a truncated one.
- **A merged file** (``results/bench.json``): :func:`merge_json` updates it under its own lock,
  which a concurrent merge waits for, so two runs' figures both land.

Imports only ``base.errors``: every layer may use it.
"""

from __future__ import annotations

import fcntl
import json
import os
import tempfile
from pathlib import Path

from base.errors import UserError


def atomic_write_bytes(path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (temp file in the same folder, fsync, os.replace)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def atomic_write_text(path, text: str) -> Path:
    return atomic_write_bytes(path, text.encode())


def atomic_write_json(path, data, indent: int | None = 1) -> Path:
    """JSON (NaN and infinities refused: they are not JSON) written atomically."""
    return atomic_write_text(path, json.dumps(data, indent=indent, allow_nan=False) + "\n")


def atomic_savefig(fig, path, **kwargs) -> Path:
    """``fig.savefig(path, **kwargs)`` atomically (the format comes from the suffix of ``path``)."""
    import io

    path = Path(path)
    buffer = io.BytesIO()
    kwargs.setdefault("format", path.suffix.lstrip(".") or "png")
    fig.savefig(buffer, **kwargs)
    return atomic_write_bytes(path, buffer.getvalue())


def merge_json(path, new: dict, what: str = "--figures") -> dict:
    """Update the JSON object in ``path`` with ``new`` (keys not in ``new`` kept) and write it
    atomically, under a lock (``.<name>.lock`` beside it) that a concurrent merge waits for: two
    merges at once both land. A file that holds no JSON object is a UserError."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd = os.open(path.parent / f".{path.name}.lock", os.O_RDWR | os.O_CREAT, 0o644)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)  # blocking: the critical section is one read and one write
        merged = read_json_object(path, what) if path.exists() else {}
        merged.update(new)
        atomic_write_text(path, json.dumps(merged, indent=2, sort_keys=True) + "\n")
        return merged
    finally:
        os.close(fd)


def read_json_object(path, what: str) -> dict:
    """The JSON object in ``path``; a UserError naming ``what`` and the file otherwise."""
    try:
        data = json.loads(Path(path).read_text())
    except (OSError, ValueError) as exc:
        raise UserError(f"{what} {str(path)!r} holds no JSON object to merge into ({exc})") from None
    if not isinstance(data, dict):
        raise UserError(f"{what} {str(path)!r} holds no JSON object to merge into (a {type(data).__name__})")
    return data

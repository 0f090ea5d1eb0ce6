"""Run folders that never lose or mix results.

- **A fresh folder per run.** Without ``--out`` a run writes ``<root>/<date>-<time>-seed<S>/``
  (``root``: e.g. ``results/model_based``) and points ``<root>/latest`` at it (a relative symlink
  swapped in atomically; a one-line text file naming the folder where symlinks fail). Two runs
  in a row keep both.
- **An explicit ``--out DIR``** that already holds a run (a summary or a checkpoint) is refused
  unless ``resume`` (continue that run: its checkpoint must exist) or ``force`` (the earlier
  run's result files are deleted first, so none of them is left beside the new ones).
- **A lock.** ``DIR/.lock`` is held with ``flock`` for the whole run: a second run on the folder is
  refused, naming the folder and the process that holds it. The kernel drops the lock when that
  process ends, however it ends (``kill -9`` too), so a stale lock is simply taken over.

Its result files are written whole or not at all (``base.files``). Imports only ``base``: every
layer (``sim_world``, ``benchmarks``, ``hdl``) may use it.
"""

from __future__ import annotations

import datetime as _dt
import fcntl
import json
import os
import shutil
import socket
import sys
import time
from pathlib import Path

from base.errors import UserError
from base.files import atomic_write_text

LOCK_NAME = ".lock"
LATEST = "latest"
# What marks a folder as holding a run, and the files a run writes (deleted by --force and, when
# a run does not write them again, after it: no earlier run's plot stays beside a new summary).
RUN_MARKERS = ("summary.json", "checkpoint.json")
RESULT_SUFFIXES = (".json", ".png", ".md", ".toml", ".csv", ".txt", ".vcd", ".tmp",
                   ".npz", ".html", ".mp4", ".gif")  # the replay's recording, the report and its video


class RunFolderError(UserError):
    """An output folder that cannot be used for this run."""


# -- the lock ------------------------------------------------------------------------------------


def _lock_holder(path: Path) -> str:
    try:
        info = json.loads(path.read_text() or "{}")
    except (OSError, ValueError):
        return "another process"
    pid, host = info.get("pid"), info.get("host")
    command = info.get("command", "")
    where = "" if host in (None, socket.gethostname()) else f" on {host}"
    return f"process {pid}{where} ({command}, since {info.get('started', '?')})"


class RunLock:
    """An exclusive ``flock`` on ``folder/.lock``; refused with a :class:`RunFolderError` that
    names the folder and the holder while another process holds it."""

    def __init__(self, folder: Path):
        self.folder = Path(folder)
        self.path = self.folder / LOCK_NAME
        self._fd: int | None = None

    def acquire(self) -> "RunLock":
        fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            raise RunFolderError(
                f"run folder {str(self.folder)!r} is in use by {_lock_holder(self.path)}; wait for "
                "it to end or choose another --out") from None
        # Ours now (a dead holder's lock is released by the kernel): say who holds it.
        info = {"pid": os.getpid(), "host": socket.gethostname(),
                "command": " ".join([Path(sys.argv[0]).name, *sys.argv[1:]])[:200],
                "started": _dt.datetime.now().isoformat(timespec="seconds")}
        os.ftruncate(fd, 0)
        os.pwrite(fd, (json.dumps(info) + "\n").encode(), 0)
        self._fd = fd
        return self

    def release(self) -> None:
        # The file stays: unlinking a lock file another process has opened would let two
        # processes hold "the" lock on two different files.
        if self._fd is not None:
            fcntl.flock(self._fd, fcntl.LOCK_UN)
            os.close(self._fd)
            self._fd = None

    def __enter__(self):
        return self.acquire() if self._fd is None else self

    def __exit__(self, *exc):
        self.release()


# -- run folders ---------------------------------------------------------------------------------


def result_files(folder: Path) -> list[Path]:
    """The files of a run in ``folder`` (recursively), by suffix; the lock is not one."""
    return sorted(p for p in Path(folder).rglob("*")
                  if p.is_file() and p.suffix in RESULT_SUFFIXES and p.name != LOCK_NAME)


def _holds_run(folder: Path, markers=RUN_MARKERS) -> list[str]:
    """The marker files (names or glob patterns) of a run that ``folder`` holds."""
    return sorted({p.name for pattern in markers for p in folder.glob(pattern) if p.is_file()})


def _other_runs(folder: Path) -> list[Path]:
    """Run folders or results roots inside ``folder`` (a lock or a ``latest`` pointer below it):
    ``--force`` replaces one run's files, never a tree of runs such as ``results/``."""
    locks = [p for p in folder.rglob(LOCK_NAME) if p.parent != folder]
    return sorted(locks + list(folder.rglob(LATEST)))


def read_latest(root: Path) -> Path | None:
    """The folder ``root/latest`` points at (symlink or text file), or None."""
    pointer = Path(root) / LATEST
    if pointer.is_symlink():
        target = pointer.resolve()
        return target if target.is_dir() else None
    if pointer.is_file():
        name = pointer.read_text().strip()
        target = Path(root) / name
        return target if name and target.is_dir() else None
    return None


def write_latest(root: Path, folder: Path) -> Path:
    """Point ``root/latest`` at ``folder`` atomically: a relative symlink, else a text file."""
    root = Path(root)
    pointer = root / LATEST
    name = os.path.relpath(Path(folder).resolve(), root.resolve())
    tmp = root / f".{LATEST}.{os.getpid()}.tmp"
    tmp.unlink(missing_ok=True)
    try:
        os.symlink(name, tmp, target_is_directory=True)
    except (OSError, NotImplementedError):
        atomic_write_text(pointer, name + "\n")
        return pointer
    if pointer.is_dir() and not pointer.is_symlink():  # an old real folder called "latest"
        tmp.unlink()
        raise RunFolderError(f"{str(pointer)!r} is a folder, not a pointer: rename it")
    os.replace(tmp, pointer)
    return pointer


def _fresh_folder(root: Path, label: str | None) -> Path:
    stamp = _dt.datetime.now().strftime("%Y%m%d-%H%M%S")
    base = stamp + ("" if not label else f"-{label}")
    for n in range(1, 1000):
        folder = root / (base if n == 1 else f"{base}-{n}")
        try:
            folder.mkdir(parents=True)  # the atomic claim: two runs never share a folder
            return folder
        except FileExistsError:
            continue
    raise RunFolderError(f"cannot make a fresh run folder under {str(root)!r}")


def _check_writable(folder: Path, what: str) -> None:
    if folder.exists() and not folder.is_dir():
        raise RunFolderError(f"{what} {str(folder)!r} is a file, not a folder")
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise RunFolderError(f"cannot create {what} {str(folder)!r}: {exc.strerror}") from None
    if not os.access(folder, os.W_OK | os.X_OK):
        raise RunFolderError(f"{what} {str(folder)!r} is not writable")


class RunFolder:
    """The folder of one run, locked while in use: ``with open_run(...) as run_dir: ...``."""

    def __init__(self, path: Path, lock: RunLock, fresh: bool, resumed: bool,
                 root: Path | None = None, previous: Path | None = None,
                 keep_marker: str | None = "checkpoint.json"):
        self.path = Path(path)
        self.lock = lock
        self.fresh = fresh
        self.resumed = resumed
        self.started_ns = time.time_ns()
        self._root, self._previous = root, previous  # where `latest` pointed before
        self._keep_marker = keep_marker  # a failed run that wrote it is kept (resumable)
        self._before = None  # (paths that existed, {small file: its text}) of an --out folder

    def remember(self, existed: set, keep=("config.toml", "sessions.json")) -> "RunFolder":
        """What ``restore`` puts back: the paths in the folder before this session (an empty set
        when the folder did not exist) and the text of the small files a start rewrites."""
        saved = {}
        for name in keep:
            p = self.path / name
            if p in existed and p.is_file():
                try:
                    saved[p] = p.read_text()
                except (OSError, UnicodeDecodeError):
                    pass
        self._before = (set(existed), saved)
        return self

    def __enter__(self) -> "RunFolder":
        return self

    def __exit__(self, exc_type, exc, tb):
        try:
            if exc_type is not None and not self._progressed():
                if self.fresh:  # a fresh run that failed before its first checkpoint: nothing to resume
                    self.discard()
                else:
                    self.restore()
        finally:
            self.lock.release()

    def _progressed(self) -> bool:
        """Whether this session wrote its checkpoint (then the folder is kept: ``--resume``)."""
        if not self._keep_marker:
            return False
        marker = self.path / self._keep_marker
        return marker.exists() and marker.stat().st_mtime_ns >= self.started_ns

    def restore(self) -> None:
        """A start that failed leaves an ``--out`` folder as it was: the files this session made
        are deleted (the lock file too, if it made it: unlinked while still held, so no other
        process can take the old file's lock meanwhile), the small files it rewrote
        (``config.toml``, ``sessions.json``) get their old bytes back, and a folder it created goes."""
        if self._before is None:
            return
        existed, saved = self._before
        for p in sorted(self.path.rglob("*"), reverse=True):
            if p in existed:
                continue
            if p.is_dir() and not p.is_symlink():
                try:
                    p.rmdir()
                except OSError:
                    pass
            else:
                p.unlink(missing_ok=True)
        for p, content in saved.items():
            atomic_write_text(p, content)
        if self.path not in existed:  # the folder itself was made by this session
            try:
                self.path.rmdir()
            except OSError:
                pass

    def discard(self) -> None:
        """Remove a fresh run's folder (no half-made folder stays) and point `latest` where it
        pointed before; an ``--out`` folder is put back as it was (:meth:`restore`)."""
        if not self.fresh:
            self.restore()
            return
        shutil.rmtree(self.path, ignore_errors=True)
        if self._root is not None:
            if self._previous is not None:
                write_latest(self._root, self._previous)
            else:
                (self._root / LATEST).unlink(missing_ok=True)

    def close(self) -> None:
        self.lock.release()

    def remove_stale(self, written=(), keep=("checkpoint.json", "config.toml", "sessions.json")) -> list[Path]:
        """Delete the result files of an earlier session that this one did not write again: a
        file older than this session's start, not in ``written`` and not named in ``keep`` (e.g.
        a plot when this session made none). Files this session wrote (or a process it started,
        such as the cocotb simulator) are newer and stay."""
        written = {Path(p).resolve() for p in written}
        removed = []
        for p in result_files(self.path):
            if p.resolve() in written or p.name in keep or p.stat().st_mtime_ns >= self.started_ns:
                continue
            p.unlink(missing_ok=True)
            removed.append(p)
        return removed


def open_run(out, root, seed: int | None = None, *, resume: bool = False, force: bool = False,
             checkpoint: str | None = "checkpoint.json", markers=RUN_MARKERS,
             label: str | None = None) -> RunFolder:
    """The locked folder of a run (see the module docstring).

    ``out``: the ``--out`` folder or None (a fresh folder under ``root``, named
    ``<date>-<time>-<label>``, the label ``seed<S>`` by default; or with ``resume`` the one
    ``root/latest`` points at). ``checkpoint``: the file a resume needs (None: the command has no
    checkpoints and cannot resume). ``markers``: the files (names or glob patterns) that show a
    folder holds a run of this command.
    """
    if label is None and seed is not None:
        label = f"seed{seed}"
    if resume and force:
        raise RunFolderError("--resume and --force exclude each other: resume a run, or replace it")
    if resume and checkpoint is None:
        raise RunFolderError("--resume: this command keeps no checkpoint, there is nothing to resume")
    root = Path(root)
    fresh = False
    previous = read_latest(root)
    if out is None:
        if resume:
            folder = read_latest(root)
            if folder is None:
                raise RunFolderError(f"--resume without --out continues {str(root / LATEST)!r}, "
                                     "which points at no run folder; give --out DIR")
        else:
            _check_writable(root, "results folder")
            folder, fresh = _fresh_folder(root, label), True
    else:
        folder = Path(out)
        if resume and not folder.is_dir():
            raise RunFolderError(f"--resume: {str(folder)!r} is not a run folder")
        existed = set(folder.rglob("*")) | {folder} if folder.is_dir() else set()
        _check_writable(folder, "output folder --out")
    lock = RunLock(folder).acquire()
    run_folder = RunFolder(folder, lock, fresh=fresh, resumed=resume, root=root, previous=previous,
                           keep_marker=checkpoint)
    if out is not None:
        run_folder.remember(existed)
    try:
        held = _holds_run(folder, markers)
        if resume:
            if not (folder / checkpoint).is_file():
                raise RunFolderError(f"--resume: {str(folder)!r} holds no {checkpoint} to resume from")
        elif held and not force:
            resume_hint = "--resume to continue it, " if checkpoint is not None else ""
            raise RunFolderError(
                f"--out {str(folder)!r} already holds a run ({', '.join(held)}): give {resume_hint}"
                "--force to replace it, or another --out (without --out every run gets a fresh "
                "folder)")
        elif force:
            nested = _other_runs(folder)
            if nested:
                raise RunFolderError(
                    f"--force: {str(folder)!r} is not one run's folder, it holds other runs "
                    f"({str(nested[0])!r}); give the run's own folder as --out")
            for p in result_files(folder):
                p.unlink(missing_ok=True)
            for d in sorted((p for p in folder.rglob("*") if p.is_dir()), reverse=True):
                try:
                    d.rmdir()  # emptied sub-folders of the earlier run
                except OSError:
                    pass
        if fresh or out is None:
            write_latest(root, folder)
    except BaseException:
        if fresh:
            shutil.rmtree(folder, ignore_errors=True)
        else:
            run_folder.restore()
        lock.release()
        raise
    return run_folder

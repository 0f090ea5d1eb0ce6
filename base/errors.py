"""The project's user-error type and the one wrapper every entry point runs under.

A *user error* is something the person running a command can fix: a bad option, a missing or
corrupt input file, a folder in use. It ends the command with one line on stderr::

    error: <what, naming the file, option or field>

and exit status 2 (argparse's own status for a bad command line). Anything else is a bug and keeps
its traceback. Modules raise :class:`UserError` (or a subclass: ``sim_world.arena.ArenaError``,
``base.checkpoint.CheckpointError``, ...) and never print the line themselves;
:func:`run_main` prints it.

This module imports nothing from the project, so any layer (``sim_world`` too) may use it.
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading
from typing import Callable, Sequence

EXIT_USER_ERROR = 2


class UserError(Exception):
    """An error in what the user gave (options, files, environment); the message says what."""


def error_line(exc: BaseException) -> str:
    """The one line a user error prints (its message on one line)."""
    text = " ".join(str(exc).split()) or type(exc).__name__
    return f"error: {text}"


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised where the program is (as SIGINT raises KeyboardInterrupt), so the same
    clean-up runs and the same ``error: interrupted`` line is printed."""


def _terminate(signum, frame):
    raise Terminated()


def run_main(main: Callable[[Sequence[str] | None], int | None], argv: Sequence[str] | None = None) -> int:
    """Run ``main(argv)``; a :class:`UserError` becomes one ``error:`` line and exit status 2;
    SIGINT and SIGTERM one ``error: interrupted`` line (exit 130 and 143)."""
    previous = None
    if threading.current_thread() is threading.main_thread():
        previous = signal.signal(signal.SIGTERM, _terminate)
    try:
        return _run(main, argv)
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


def _run(main, argv) -> int:
    try:
        return int(main(argv) or 0)
    except UserError as exc:
        sys.stdout.flush()
        print(error_line(exc), file=sys.stderr)
        return EXIT_USER_ERROR
    except SystemExit as exc:  # argparse: --help (0) or a bad command line (2, its line printed)
        if exc.code is None or isinstance(exc.code, int):
            return int(exc.code or 0)
        raise
    except KeyboardInterrupt as exc:
        sys.stdout.flush()
        print("error: interrupted", file=sys.stderr)
        return 128 + (signal.SIGTERM if isinstance(exc, Terminated) else signal.SIGINT)


class ArgumentParser(argparse.ArgumentParser):
    """argparse with the project's error convention: a bad command line is one ``error:`` line
    (naming the option and the command's ``--help``) and exit status 2, not a usage block."""

    def error(self, message: str):  # noqa: D102 - argparse's hook
        raise SystemExit(_argparse_exit(self.prog, message))


def _argparse_exit(prog: str, message: str) -> int:
    sys.stdout.flush()
    print(f"error: {' '.join(message.split())} (see '{prog} --help')", file=sys.stderr)
    return EXIT_USER_ERROR

"""``ehw replay`` and ``ehw report``: parsers and commands (``cosim.report``), and the report that
``ehw sim``, ``ehw offline`` and ``ehw compare`` write at their end unless ``--no-report``."""

from __future__ import annotations

import math
from pathlib import Path

from base.errors import UserError
from base.runs import RunLock
from cosim.cli.options import RESULTS

DEFAULT_RUN = RESULTS / "model_based" / "latest"


def _run_dir_argument(p) -> None:
    p.add_argument("run_dir", type=Path, nargs="?", default=DEFAULT_RUN, metavar="RUN_DIR",
                   help="a run folder of ehw sim or ehw offline (report: also ehw compare; default: the latest ehw sim run)")


def _video_options(p) -> None:
    from cosim.report.replay import DEFAULT_FPS, DEFAULT_MAX_SECONDS

    p.add_argument("--fps", type=float, default=DEFAULT_FPS, help="frames per second of the video")
    p.add_argument("--max-seconds", type=float, default=DEFAULT_MAX_SECONDS,
                   help="the longest video: a longer lifetime is sampled evenly down to fps x max-seconds frames")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def _check(args) -> Path:
    for name in ("fps", "max_seconds"):
        value = getattr(args, name)
        if not (math.isfinite(value) and value > 0):
            raise UserError(f"--{name.replace('_', '-')} must be a positive number, got {value!r}")
    run_dir = Path(args.run_dir)
    if not run_dir.is_dir():
        raise UserError(f"no run folder {str(run_dir)!r}")
    return run_dir


def replay_parser(p) -> None:
    _run_dir_argument(p)
    _video_options(p)
    p.add_argument("--format", choices=("auto", "mp4", "gif"), default="auto",
                   help="mp4 (H.264 through imageio-ffmpeg) or gif; auto: mp4 where ffmpeg is there")
    p.add_argument("--out", type=Path, default=None, metavar="FILE",
                   help="the video file (default: RUN_DIR/replay.mp4 or .gif)")


def cmd_replay(args, extras: dict, sub=None) -> int:
    from cosim.report.replay import ffmpeg_available, replay

    run_dir = _check(args)
    if args.format == "mp4" and not ffmpeg_available():
        raise UserError("--format mp4 needs imageio-ffmpeg (pip install imageio-ffmpeg); --format gif needs none")
    fmt = args.format
    if args.out is not None:
        fmt = args.out.suffix.lstrip(".").lower()
        if fmt not in ("mp4", "gif"):
            raise UserError(f"--out {str(args.out)!r}: the video is a .mp4 or a .gif file")
    with RunLock(run_dir).acquire():
        path = replay(run_dir, fps=args.fps, max_seconds=args.max_seconds, fmt=fmt,
                      progress=not args.quiet, out=args.out)
    print(f"wrote {path}")
    return 0


def report_parser(p) -> None:
    _run_dir_argument(p)
    _video_options(p)


def cmd_report(args, extras: dict, sub=None) -> int:
    run_dir = _check(args)
    with RunLock(run_dir).acquire():
        path = write_report(run_dir, fps=args.fps, max_seconds=args.max_seconds, progress=not args.quiet)
    print(f"wrote {path}")
    return 0


# -- the report at the end of a run ---------------------------------------------------------------


def add_report_flag(p) -> None:
    p.add_argument("--no-report", action="store_true",
                   help="write no report.html (nor replay video) at the end; `ehw report RUN_DIR` writes it later")


def write_report(run_dir: Path, **options) -> Path:
    from cosim.report.html import write_report as write

    return write(run_dir, **options)


def report_at_end(args, run_dir: Path, plots: bool = True) -> Path | None:
    """After a run (inside its folder's lock): its report.html, unless --no-report or --no-plots."""
    if getattr(args, "no_report", False) or not plots:
        return None
    quiet = getattr(args, "quiet", False) or getattr(args, "no_progress", False)
    path = write_report(run_dir, progress=not quiet)
    print(f"wrote {path}")
    return path

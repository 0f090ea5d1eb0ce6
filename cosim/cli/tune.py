"""``ehw tune METHOD``: equal-effort tuning of one learning method (``cosim.compare.tune``)."""

from __future__ import annotations

from pathlib import Path

from base.errors import UserError


def parse_seeds(text: str) -> list[int]:
    """``1001-1005`` or ``1001,1003,1007`` (or both, comma-separated) -> the seeds, each once."""
    seeds: list[int] = []
    try:
        for part in text.split(","):
            first, _, last = part.strip().partition("-")
            seeds += range(int(first), int(last or first) + 1)
    except ValueError:
        raise UserError(f"--seeds must be like 1001-1005 or 1001,1002, got {text!r}") from None
    if not seeds or min(seeds) < 0 or len(set(seeds)) != len(seeds):
        raise UserError(f"--seeds must name distinct seeds >= 0, got {text!r}")
    return seeds


def tune_parser(p) -> None:
    from cosim.compare.report import SHAPINGS
    from cosim.compare.tune import METHODS, TUNE_ROOT

    p.add_argument("method", metavar="METHOD", help=f"the method to tune: {', '.join(METHODS)}")
    p.add_argument("--trials", type=int, required=True, help="finished trials of the study (the budget, "
                   "the same for every method); a re-run continues the study up to it")
    p.add_argument("--seeds", default="1001-1005", help="the tuning seeds, never the reported ones "
                   "(default %(default)s)")
    p.add_argument("--shaping", choices=SHAPINGS, default="shaped", help="the peers' reward (default %(default)s)")
    p.add_argument("--arena", default="default")
    p.add_argument("--jobs", type=int, default=2, help="lifetimes run at once (default %(default)s)")
    p.add_argument("--sampler-seed", type=int, default=0, help="the TPE sampler's seed (default %(default)s)")
    p.add_argument("--out", type=Path, default=TUNE_ROOT, help="the studies' folder: <method>[-<shaping>].db "
                   "(SQLite) and .json (default %(default)s)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def cmd_tune(args, extras: dict, sub=None) -> int:
    from cosim.compare.tune import check_method, report_text, tune

    check_method(args.method)
    if args.trials < 1:
        raise UserError(f"--trials must be at least 1, got {args.trials!r}")
    if args.jobs < 1:
        raise UserError(f"--jobs must be at least 1, got {args.jobs!r}")
    from sim_world.arena import load_arena

    load_arena(args.arena)
    report = tune(args.method, parse_seeds(args.seeds), args.trials, shaping=args.shaping, arena=args.arena,
                  out=args.out, jobs=args.jobs, sampler_seed=args.sampler_seed, progress=not args.quiet)
    print(report_text(report))
    return 0

"""The options of the comparison: ``ehw compare`` (``cosim.cli.main``, which adds ``--config``)
puts :func:`add_arguments` on its parser and runs :func:`check_args` before any work (one
``error:`` line naming the option for a bad value).

Where a comparison's files go (``base.runs``): its tables (``compare.json``, ``compare.md``,
``compare.png``) and its ``config.toml`` in a fresh run folder
``results/compare/<date>-<time>-seeds<A>-<B>/`` with ``results/compare/latest`` pointing at it
(``--out DIR``: that folder, refused when it holds a comparison unless ``--force``). The lifetime
cache (``results/compare/cache``, keyed by method, config and seed) and the lifetimes' own
checkpoint folders (``results/compare/model_based|model_free|adaptation/seed_<S>/``) are shared
by every comparison.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
from pathlib import Path

from base.errors import UserError
from cosim.compare.report import DEEP, DEFAULT_METHODS, METHODS, N_TARGETS, OPTIONAL, SHAPINGS, TABULAR

COMPARE_ROOT = Path("results/compare")
CACHE = COMPARE_ROOT / "cache"
# What says how a comparison runs, never what it computes: not recorded in its config.toml, and
# free to change on --resume.
NOT_RECORDED = {"out", "resume", "force", "config", "quiet", "help", "render", "reuse",
                "adaptation_only", "fresh"}
HOW_IT_RUNS = {"jobs", "cluster", "cache"}


def add_arguments(p: argparse.ArgumentParser) -> argparse.ArgumentParser:
    """The comparison's options (each with its help; the parser's formatter shows the defaults)."""
    p.add_argument("--seeds", type=int, default=5, metavar="N", help="how many seeds: FIRST..FIRST+N-1")
    p.add_argument("--first-seed", type=int, default=1, metavar="FIRST", help="the first seed")
    p.add_argument("--methods", default=",".join(DEFAULT_METHODS), metavar="M,M,...",
                   help=f"comma-separated, from {','.join(METHODS)} ({','.join(OPTIONAL)} need "
                        "the [rl] extra)")
    p.add_argument("--shaping", default=",".join(SHAPINGS), metavar="S,S",
                   help="reward variants of the RL methods: shaped, unshaped or both")
    p.add_argument("--arena", default="default", metavar="NAME|FILE", help="arena name or .json path")
    p.add_argument("--limit-seeds", action="append", default=[], metavar="ROW=N",
                   help="run only the first N seeds for ROW, a method or method/shaping "
                        "(e.g. offline=5,q-learning/unshaped=10; 0: none): slow rows on fewer seeds (repeatable)")
    p.add_argument("--max-interactions", type=int, default=None, metavar="N",
                   help="cap of an RL lifetime (default: 100,000, as the on-line run's)")
    p.add_argument("--generations-cap", type=int, default=None, metavar="G",
                   help="off-line generation cap (default: cosim.offline.run's)")
    p.add_argument("--distance", choices=("covered", "forward"), default="forward",
                   help="dist[a] of the on-line fitness: forward = SPEC section 7, backward steps "
                        "cover 0; covered = the paper's first reading (docs/research-log.md, on-line round 5)")
    p.add_argument("--online", action="append", default=[], metavar="KEY=VALUE",
                   help="an OnlineConfig field for the on-line runs, e.g. loop_cycles=0 (repeatable)")
    p.add_argument("--blind-bit", type=int, default=None, metavar="B",
                   help="adaptation (paper 5.2): blind IR bit B (0..5) of the on-line run ...")
    p.add_argument("--blind-after-target", type=int, default=None, metavar="T",
                   help="... after target T, and count the interactions of the next 8 targets")
    p.add_argument("--planner-limit", action=argparse.BooleanOptionalAction, default=True,
                   help="plan the arena's limit (the omniscient planner of 'ehw limit', cached) and show every "
                        "method's median as a multiple of it")
    p.add_argument("--jobs", type=int, default=2, metavar="J", help="worker processes")
    p.add_argument("--cluster", default=None, metavar="local|ADDRESS",
                   help="run the lifetimes on Dask: 'local' starts a LocalCluster of --jobs workers on "
                        "127.0.0.1; an address (tcp://host:8786) joins that scheduler (default: a "
                        "local process pool)")
    p.add_argument("--cache", type=Path, default=CACHE, metavar="DIR",
                   help="the lifetime cache, shared by every comparison (by method, config and seed)")
    p.add_argument("--fresh", action="store_true", help="ignore cached lifetimes (they are overwritten)")
    p.add_argument("--out", type=Path, default=None, metavar="DIR",
                   help=f"the folder of the tables (default: a fresh {COMPARE_ROOT}/<date>-<time>-seeds<A>-<B>/, "
                        f"with {COMPARE_ROOT}/latest pointing at it)")
    p.add_argument("--resume", action="store_true",
                   help="continue the comparison in --out (without --out: the one 'latest' points at) "
                        "under its config.toml: cached lifetimes are kept, on-line/off-line lifetimes "
                        "not in the cache continue from their checkpoints")
    p.add_argument("--force", action="store_true",
                   help="replace the comparison --out holds (its files are deleted first)")
    p.add_argument("--quiet", action="store_true", help="no line per finished lifetime")
    p.add_argument("--adaptation-only", action="store_true",
                   help="with --blind-bit: run only the adaptation runs and add them to the comparison "
                        "in --out (default: latest); its off-line controllers come from its model_free runs")
    p.add_argument("--reuse", nargs="?", const="latest", default=None, metavar="DIR|FILE",
                   help="take the methods not run now (not in --methods) from an earlier comparison "
                        "(its folder or compare.json; alone: the one 'latest' points at)")
    p.add_argument("--render", type=Path, default=None, metavar="JSON",
                   help="only rewrite compare.md and compare.png beside an existing compare.json")
    return p


# -- the checks -----------------------------------------------------------------------------------


def online_options(items: list[str]) -> dict:
    """``["distance_rule=covered", "loop_cycles=0"]`` -> OnlineConfig fields of the right types
    (a bad item is a UserError naming it; a value OnlineConfig refuses, its ValueError)."""
    from cosim.online.config import OnlineConfig

    fields = {f.name: type(getattr(OnlineConfig(), f.name)) for f in dataclasses.fields(OnlineConfig)}
    options = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or key not in fields or key == "seed":
            raise UserError(f"--online wants KEY=VALUE with KEY an OnlineConfig field, got {item!r}")
        kind = fields[key]
        try:
            if kind is bool:
                if value.lower() not in ("1", "true", "yes", "0", "false", "no"):
                    raise ValueError(value)
                options[key] = value.lower() in ("1", "true", "yes")
            else:
                options[key] = value if kind in (str, type(None)) else kind(value)
        except ValueError:
            raise UserError(f"--online {item!r}: {key} takes a {kind.__name__}") from None
        number = options[key]
        if isinstance(number, (int, float)) and not isinstance(number, bool) and \
                not (math.isfinite(number) and number >= 0):
            raise UserError(f"--online {item!r}: {key} must be a finite number >= 0")
    OnlineConfig(**options)  # refuse a bad value now, not in a worker
    return options


def _row_known(row: str) -> bool:
    method, slash, shaping = row.partition("/")
    if method not in METHODS:
        return False
    if slash:
        return method in TABULAR + DEEP and shaping in SHAPINGS
    return True


def limits_of(items: list[str]) -> dict[str, int]:
    """``["offline=5,q-learning/unshaped=10"]`` -> ``{"offline": 5, "q-learning/unshaped": 10}``."""
    limits = {}
    for item in ",".join(items).split(","):
        row, sep, n = item.strip().partition("=")
        if not item.strip():
            continue
        if not sep or not n.strip().isdigit() or not _row_known(row.strip()):
            raise UserError(f"--limit-seeds wants ROW=N with ROW a method or method/shaping and N >= 0 "
                            f"(0: the row is not run), got {item.strip()!r}")
        limits[row.strip()] = int(n)
    return limits


def read_report(path: Path, option: str) -> dict:
    """The compare report at ``path`` (a folder: its compare.json), checked; else a UserError."""
    path = Path(path)
    if path.is_dir() or path.suffix != ".json":
        path = path / "compare.json"
    try:
        report = json.loads(path.read_text())
    except OSError as exc:
        raise UserError(f"{option} reads {str(path)!r}, which cannot be read ({exc.strerror}): "
                        "run 'ehw compare' first") from None
    except ValueError as exc:
        raise UserError(f"{option}: {str(path)!r} is not valid JSON ({exc})") from None
    if not isinstance(report, dict) or not isinstance(report.get("per_seed"), dict):
        raise UserError(f"{option}: {str(path)!r} is not a compare report (no per_seed)")
    try:
        report["per_seed"] = {m: {int(s): v for s, v in per.items()} for m, per in report["per_seed"].items()}
    except (AttributeError, TypeError, ValueError):
        raise UserError(f"{option}: {str(path)!r} is not a compare report (per_seed by seed)") from None
    return report


def _folder_of(out, option: str) -> Path:
    """The comparison ``--out`` names, or the one ``latest`` points at."""
    from base.runs import LATEST, read_latest

    folder = Path(out) if out is not None else read_latest(COMPARE_ROOT)
    if folder is None:
        raise UserError(f"{option} without --out reads {str(COMPARE_ROOT / LATEST)!r}, which points "
                        "at no comparison; give --out DIR")
    return folder


def check_args(args) -> argparse.Namespace:
    """Every option checked before any work; adds the parsed lists to ``args`` and returns it:
    ``methods``/``shapings`` (lists), ``limits``, ``online_fields``, ``seed_list``, ``reused``
    (the earlier report of --reuse or --adaptation-only, else None)."""
    for name, least in (("seeds", 1), ("jobs", 1), ("first_seed", 0)):
        if getattr(args, name) < least:
            raise UserError(f"--{name.replace('_', '-')} must be at least {least}, got {getattr(args, name)!r}")
    for name in ("max_interactions", "generations_cap"):
        if getattr(args, name) is not None and getattr(args, name) < 1:
            raise UserError(f"--{name.replace('_', '-')} must be at least 1, got {getattr(args, name)!r}")
    methods = [m.strip() for m in args.methods.split(",") if m.strip()]
    bad = [m for m in methods if m not in METHODS]
    if bad or not methods:
        raise UserError(f"--methods: unknown method(s) {', '.join(bad) or repr(args.methods)}; "
                        f"choose from {', '.join(METHODS)}")
    shapings = [s.strip() for s in args.shaping.split(",") if s.strip()]
    if not shapings or any(s not in SHAPINGS for s in shapings):
        raise UserError(f"--shaping takes {' and/or '.join(SHAPINGS)}, got {args.shaping!r}")
    if any(m in DEEP for m in methods) and not args.adaptation_only:
        try:
            import stable_baselines3  # noqa: F401
        except ImportError:
            raise UserError("--methods dqn and ppo need the optional extra: pip install -e '.[rl]'") from None
    if (args.blind_bit is None) != (args.blind_after_target is None):
        raise UserError("--blind-bit and --blind-after-target go together")
    if args.blind_bit is not None:
        if args.blind_bit not in range(6):
            raise UserError(f"--blind-bit must be an IR bit 0..5, got {args.blind_bit!r}")
        if not 1 <= args.blind_after_target < N_TARGETS:
            raise UserError(f"--blind-after-target must be a target 1..{N_TARGETS - 1}, got "
                            f"{args.blind_after_target!r}")
    if args.adaptation_only and args.blind_bit is None:
        raise UserError("--adaptation-only needs --blind-bit B and --blind-after-target T")
    if args.adaptation_only and args.reuse is not None:
        raise UserError("--adaptation-only extends the comparison in --out; --reuse makes a new one")
    if args.resume and args.force:
        raise UserError("--resume and --force exclude each other: resume a comparison, or replace it")
    args.limits = limits_of(args.limit_seeds)
    online = {} if args.distance == "forward" else {"distance_rule": args.distance}
    try:
        online.update(online_options(args.online))
    except (ValueError, TypeError) as exc:
        raise UserError(f"--online: {exc}") from None
    args.online_fields = online
    if Path(args.cache).exists() and not Path(args.cache).is_dir():
        raise UserError(f"--cache {str(args.cache)!r} is a file, not a folder")
    from sim_world.arena import load_arena

    load_arena(args.arena)  # an ArenaError names the file and the item
    args.methods_list, args.shapings = methods, shapings
    args.seed_list = list(range(args.first_seed, args.first_seed + args.seeds))
    args.reused = None
    if args.adaptation_only:
        args.reused = read_report(_folder_of(args.out, "--adaptation-only"), "--adaptation-only")
    elif args.reuse is not None:
        source = _folder_of(None if args.reuse == "latest" else args.reuse, "--reuse")
        args.reused = read_report(source, "--reuse")
    return args


def recorded_options(args) -> dict:
    """The options of a comparison as its config.toml records them (``--config`` takes it back)."""
    values = {}
    for key, value in vars(args).items():
        if key in NOT_RECORDED or key.startswith("_") or key in ("command", "passed"):
            continue
        if key in ("limits", "online_fields", "methods_list", "shapings", "seed_list", "reused"):
            continue  # derived by check_args
        values[key] = str(value) if isinstance(value, Path) else value
    return values


def check_resumed(args, folder: Path) -> None:
    """``--resume``: the options that decide the tables must be the ones stored with the run."""
    from base.config_file import read_config_file

    stored = read_config_file(folder / "config.toml")
    now = recorded_options(args)
    differ = [k for k in now if k not in HOW_IT_RUNS and stored.get(k) != now[k]]
    if differ:
        raise UserError(f"--resume continues the comparison in {str(folder)!r} under its config.toml; "
                        "these options differ from it: " +
                        ", ".join(f"--{k.replace('_', '-')} {now[k]!r} (stored {stored.get(k)!r})" for k in differ))

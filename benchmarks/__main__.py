"""Run the benchmark modules (``ehw bench``): this run's figures in its run folder
(``results/bench/<date>-<time>/bench.json``, ``results/bench/latest`` pointing at it), and merged
into ``results/bench.json``, the newest figure of every module (``--figures``)."""

from __future__ import annotations

import argparse
import importlib
import json
import os
import pkgutil
import platform
import time
from pathlib import Path

import benchmarks

RESULTS = Path("results/bench.json")


def _names() -> list[str]:
    return sorted(m.name for m in pkgutil.iter_modules(benchmarks.__path__) if m.name.startswith("bench_"))


def _load(name: str):
    """The benchmark module ``benchmarks.<name>``."""
    return importlib.import_module(f"benchmarks.{name}")


def add_arguments(parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
    parser.add_argument("only", nargs="*", metavar="MODULE",
                        help=f"modules to run (default: all of {', '.join(_names())})")
    parser.add_argument("--out", type=Path, default=None, metavar="DIR",
                        help="the run folder of this run's bench.json (default: a fresh "
                             "results/bench/<date>-<time>/, with results/bench/latest pointing at it)")
    parser.add_argument("--figures", type=Path, default=RESULTS, metavar="FILE",
                        help="every module's newest figures: this run's are merged in (atomically, "
                             "under a lock)")
    return parser


def check_args(args) -> None:
    """The modules named and the figures file, checked before any benchmark runs."""
    from base.errors import UserError
    from base.files import read_json_object

    names = _names()
    unknown = set(args.only) - set(names)
    if unknown:
        raise UserError(f"unknown benchmark module(s) {sorted(unknown)}; known: {names}")
    if args.out is not None and (args.out.suffix == ".json" or args.out.resolve() == args.figures.resolve()):
        raise UserError(f"--out {str(args.out)!r} is the run folder of this run's bench.json, not a "
                        f"file; the merged figures file is --figures (default {str(RESULTS)!r})")
    if args.figures.exists():
        if args.figures.is_dir():
            raise UserError(f"--figures {str(args.figures)!r} is a folder, not a file")
        read_json_object(args.figures, "--figures")


def run_from_args(args, folder: Path) -> int:
    """Run the modules of checked ``args``; write ``folder/bench.json`` and merge into --figures."""
    from base.files import atomic_write_text, merge_json

    figures = {}
    for name in args.only or _names():
        print(f"== {name}", flush=True)
        t0 = time.perf_counter()
        result = _load(name).run()
        for key, value in result.items():
            print(f"  {key:40s} {value}")
        figures.update(result)
        print(f"  ({time.perf_counter() - t0:.1f} s)")
    figures["_machine"] = {"python": platform.python_version(), "cpus": os.cpu_count(), "time": time.strftime("%Y-%m-%dT%H:%M:%S")}
    atomic_write_text(Path(folder) / "bench.json", json.dumps(figures, indent=2, sort_keys=True) + "\n")
    merge_json(args.figures, figures)
    print(f"wrote {Path(folder) / 'bench.json'} and merged it into {args.figures}")
    return 0


def main(argv=None) -> int:
    """``ehw bench`` (and ``python -m benchmarks``): the exit status; a user error is one line."""
    from base.errors import ArgumentParser, run_main
    from base.options import PROG, HelpFormatter, add_common
    from base.runs import open_run

    def _main(argv) -> int:
        parser = ArgumentParser(prog=f"{PROG} bench", formatter_class=HelpFormatter,
                                description="speed figures -> results/bench/<date>-<time>/bench.json, "
                                            "merged into results/bench.json")
        add_arguments(parser)
        add_common(parser, seed=False, resume=False, quiet=False, config=False)  # --force
        args = parser.parse_args(argv)
        from cosim.cli.options import resolve_hdl_settings

        resolve_hdl_settings(argparse.Namespace(backend="cocotb"))  # the environment's values checked first
        check_args(args)
        with open_run(args.out, RESULTS.parent / "bench", force=args.force, checkpoint=None,
                      markers=("bench.json",)) as run_dir:
            run_from_args(args, run_dir.path)
            run_dir.remove_stale()
        return 0

    return run_main(_main, argv)


if __name__ == "__main__":
    raise SystemExit(main())

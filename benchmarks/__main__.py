"""Run the benchmark modules and merge their figures into results/bench.json."""

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


def add_arguments(parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
    parser.add_argument("only", nargs="*", metavar="MODULE",
                        help=f"modules to run (default: all of {', '.join(_names())})")
    parser.add_argument("--out", type=Path, default=RESULTS, metavar="FILE",
                        help="the figures file (merged into an existing one)")
    return parser


def run_from_args(args) -> int:
    from cosim.errors import UserError
    from cosim.runs import atomic_write_text

    names = _names()
    unknown = set(args.only) - set(names)
    if unknown:
        raise UserError(f"unknown benchmark module(s) {sorted(unknown)}; known: {names}")
    figures = {}
    if args.out.exists():
        try:
            figures = json.loads(args.out.read_text())
        except (OSError, ValueError) as exc:
            raise UserError(f"--out {str(args.out)!r} holds no figures to merge into ({exc})") from None
    for name in args.only or names:
        print(f"== {name}", flush=True)
        t0 = time.perf_counter()
        result = importlib.import_module(f"benchmarks.{name}").run()
        for key, value in result.items():
            print(f"  {key:40s} {value}")
        figures.update(result)
        print(f"  ({time.perf_counter() - t0:.1f} s)")
    figures["_machine"] = {"python": platform.python_version(), "cpus": os.cpu_count(), "time": time.strftime("%Y-%m-%dT%H:%M:%S")}
    atomic_write_text(args.out, json.dumps(figures, indent=2, sort_keys=True) + "\n")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":  # ``python -m benchmarks`` is ``ehw bench``
    import sys

    from cosim.cli import main

    raise SystemExit(main(["bench", *sys.argv[1:]]))

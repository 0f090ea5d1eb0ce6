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


def main(argv=None) -> None:
    names = sorted(m.name for m in pkgutil.iter_modules(benchmarks.__path__) if m.name.startswith("bench_"))
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("only", nargs="*", help=f"modules to run (default all: {', '.join(names)})")
    parser.add_argument("--out", type=Path, default=RESULTS)
    args = parser.parse_args(argv)
    unknown = set(args.only) - set(names)
    if unknown:
        parser.error(f"unknown benchmark module(s) {sorted(unknown)}; known: {names}")
    figures = json.loads(args.out.read_text()) if args.out.exists() else {}
    for name in args.only or names:
        print(f"== {name}", flush=True)
        t0 = time.perf_counter()
        result = importlib.import_module(f"benchmarks.{name}").run()
        for key, value in result.items():
            print(f"  {key:40s} {value}")
        figures.update(result)
        print(f"  ({time.perf_counter() - t0:.1f} s)")
    figures["_machine"] = {"python": platform.python_version(), "cpus": os.cpu_count(), "time": time.strftime("%Y-%m-%dT%H:%M:%S")}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    tmp = args.out.with_suffix(".tmp")
    tmp.write_text(json.dumps(figures, indent=2, sort_keys=True) + "\n")
    tmp.replace(args.out)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()

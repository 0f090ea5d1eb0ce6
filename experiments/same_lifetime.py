"""Do two on-line summaries describe the same lifetime? Field by field, ignoring wall time.

    python experiments/same_lifetime.py build/before_new/summary.json results/model_based/summary.json

Compares every field of the two ``summary.json`` files (phases and targets record by record)
except the wall time, the board cycles of the HDL backends and the reference CPU time; in
``config``, only the fields both summaries have (an option that was dropped is not a
difference). Exit status 0 when equal, 1 otherwise (the differences are printed).
"""

from __future__ import annotations

import json
import sys

IGNORED = {"wall_time_s", "reference_evaluator_time_s", "backend", "board_cycles", "plots"}


def differences(a, b, path: str = "") -> list[str]:
    if isinstance(a, dict) and isinstance(b, dict):
        keys = set(a) & set(b) if path.endswith("config") else set(a) | set(b)
        out = []
        for k in sorted(keys - IGNORED):
            if k not in a or k not in b:
                out.append(f"{path}.{k}: only in {'the first' if k in a else 'the second'}")
            else:
                out += differences(a[k], b[k], f"{path}.{k}")
        return out
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return [f"{path}: {len(a)} entries vs {len(b)}"]
        return [d for i, (x, y) in enumerate(zip(a, b)) for d in differences(x, y, f"{path}[{i}]")]
    return [] if a == b else [f"{path}: {a!r} vs {b!r}"]


def main(argv=None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if len(args) != 2:
        print("usage: python experiments/same_lifetime.py A/summary.json B/summary.json", file=sys.stderr)
        return 2
    a, b = (json.load(open(p)) for p in args)
    found = differences(a, b)
    for line in found[:40]:
        print(line)
    figures = ("interactions", "generations", "world_states", "transitions", "targets_reached")
    print(" / ".join(f"{k} {a.get(k)}" for k in figures))
    print("same lifetime" if not found else f"{len(found)} differences")
    return 0 if not found else 1


if __name__ == "__main__":
    raise SystemExit(main())

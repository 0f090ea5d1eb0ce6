"""The one place that names the Verilog ports and internal registers the formal harnesses use.

The harnesses (``formal/*.sv``) connect the device under test through the macro ``DUT_PORTS`` and
read its internal registers through *probes*; both are generated from the tables below, so a
change of the generated Verilog's port names (e.g. a ``wiring.Signature`` port ``row`` that
Amaranth writes as ``row__addr``) is one edit here.

Each table maps the harness's signal name to the Verilog name in the generated module.
"""

from __future__ import annotations

# ControllerEHW (hdl/controller_ehw.py), module controller_ehw.
CONTROLLER_PORTS = {
    "clk": "clk",
    "rst": "rst",
    "row_addr": "row__addr",
    "row_data": "row__data",
    "row_we": "row__we",
    "commit": "commit",
    "x": "x",
    "reflex_en": "reflex_en",
    "motion": "motion",
}
# Internal registers of controller_ehw that the induction needs (harness wire -> DUT wire):
# the active configuration (driving the array) and the shadow (filled by the row port).
CONTROLLER_PROBES = {
    "probe_active": "active",
    "probe_shadow": "shadow",
}


# EvaluatorEHW (hdl/evaluator_ehw.py), module evaluator_ehw.
EVALUATOR_PORTS = {
    "clk": "clk",
    "rst": "rst",
    "row_addr": "row__addr",
    "row_data": "row__data",
    "row_we": "row__we",
    "model_state": "model__state",
    "model_motion": "model__motion",
    "model_next": "model__next",
    "model_crash": "model__crash",
    "model_valid": "model__valid",
    "model_we": "model__we",
    "rate_state": "rate__state",
    "rate_motion": "rate__motion",
    "rate_code": "rate__code",
    "rate_we": "rate__we",
    "state_value": "state_value",
    "state_we": "state_we",
    "clear": "clear",
    "reflex_en": "reflex_en",
    "start": "start",
    "ready": "ready",
    "busy": "busy",
    "done": "done",
    "crashes": "crashes",
    "loops": "loops",
    "distance": "distance",
    "fails": "fails",
    "cycles": "cycles",
    "n_states": "n_states",
}
EVALUATOR_PROBES = {
    "probe_fsm": "fsm_state",          # Amaranth's FSM state register (encoding: fsm_encoding())
    "probe_clear_addr": "clear_addr",  # the Clear sweep's address
    "probe_in_set": "in_set",          # S
    "probe_tested": "tested",
    "probe_acc_cycles": "acc_cycles",
    "probe_arch": "arch",              # the active configuration
    "probe_tracing": "tracing",        # in Trace: the RAM's read data is a live entry
    "probe_wr_en": "wr__en",           # the RAM's write port
    "probe_wr_addr": "wr__addr",
    "probe_wr_data": "wr__data",
    "probe_rate_wr_en": "rate_wr__en",  # the failure-rate RAM's write port
    "probe_rate_wr_addr": "rate_wr__addr",
    "probe_rate_wr_data": "rate_wr__data",
}
# hdl.link_protocol.FrameReceiver, module frame_receiver (the host link's frame decoder).
LINK_PORTS = {
    "clk": "clk",
    "rst": "rst",
    "valid": "data__valid",
    "payload": "data__payload",
    "ready": "data__ready",
    "header": "header",
    "done": "done",
    "ok": "ok",
    "truncated": "truncated",
}
LINK_PROBES = {
    "probe_fsm": "fsm_state",
    "probe_position": "position",
    "probe_silent": "silent",
    "probe_crc": "crc.crc_reg",   # lib.crc.Processor's CRC register
}

# The RAM abstraction: the memories' cells are deleted and their read data are harness inputs.
EVALUATOR_RAM_READ = ("rd__data", "ram_data")
EVALUATOR_RATE_READ = ("rate_rd__data", "rate_data")


def fsm_encoding(component) -> dict[str, int]:
    """State name -> code of the component's FSM (Amaranth numbers states in order of first
    mention). Read from the elaborated Module, so a reordering in hdl/ cannot go unnoticed."""
    from amaranth.hdl import Fragment

    try:
        fsm = Fragment.get(component, None).find_generated("fsm")
    except KeyError:
        raise ValueError(f"{type(component).__name__} has no FSM named 'fsm'") from None
    return dict(fsm.encoding)


def port_macro(ports: dict[str, str]) -> str:
    """A Verilog ``define`` of the named port connections ``.verilog_name(harness_name)``."""
    connections = ", ".join(f".{verilog}({harness})" for harness, verilog in ports.items())
    return f"`define DUT_PORTS {connections}\n"


def fsm_macros(encoding: dict[str, int]) -> str:
    """Verilog ``define``s FSM_<STATE> for each FSM state code."""
    return "".join(f"`define FSM_{name.upper()} {code}\n" for name, code in encoding.items())


def entry_macros() -> str:
    """Verilog ``define``s of the world-model RAM word (``hdl.ports.ModelEntry``): its width
    ``ENTRY_BITS``, the bit ``ENTRY_MOVES``, the field ``ENTRY_NEXT`` (a part-select range) and the
    codes ``ENTRY_UNKNOWN`` and ``ENTRY_CRASH`` of ``next`` in a word that does not move; and of
    the failure-rate RAM's word (``ga.fail_rates``): ``RATE_BITS`` and the Clear sweep's
    ``PRIOR_CODE``."""
    from amaranth.lib import data

    from ga.fail_rates import PRIOR_CODE, RATE_BITS
    from hdl.ports import ModelEntry

    layout = data.Layout.cast(ModelEntry)
    moves, nxt = layout["moves"], layout["next"]
    return (f"`define ENTRY_BITS {layout.size}\n"
            f"`define ENTRY_MOVES {moves.offset}\n"
            f"`define ENTRY_NEXT {nxt.offset + nxt.width - 1}:{nxt.offset}\n"
            f"`define ENTRY_UNKNOWN {ModelEntry.UNKNOWN}\n"
            f"`define ENTRY_CRASH {ModelEntry.CRASH}\n"
            f"`define RATE_BITS {RATE_BITS}\n`define PRIOR_CODE {PRIOR_CODE}\n")


def probe_commands(probes: dict[str, str], instance: str = "dut") -> list[str]:
    """Yosys commands (after ``flatten``) that drive each harness probe from the DUT's register."""
    # -nounset: the probe wire is undriven, but proc may have made other wires its aliases; a
    # plain -set would disconnect those aliases from it (and leave them free for the solver).
    return [f"connect -nounset -set {harness} {instance}.{inner}" for harness, inner in probes.items()]

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
    "row_addr": "row_addr",
    "row_data": "row_data",
    "row_we": "row_we",
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


def port_macro(ports: dict[str, str]) -> str:
    """A Verilog ``define`` of the named port connections ``.verilog_name(harness_name)``."""
    connections = ", ".join(f".{verilog}({harness})" for harness, verilog in ports.items())
    return f"`define DUT_PORTS {connections}\n"


def probe_commands(probes: dict[str, str], instance: str = "dut") -> list[str]:
    """Yosys commands (after ``flatten``) that drive each harness probe from the DUT's register."""
    return [f"connect -set {harness} {instance}.{inner}" for harness, inner in probes.items()]

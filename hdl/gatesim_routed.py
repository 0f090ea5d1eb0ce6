"""nextpnr's routed netlists (``--write``) as the cell models simulate them (``place_and_route``).

iCE40 (ICESTORM_LC, ICESTORM_RAM, SB_IO, SB_GB): each clock pin's path into its global buffer made a
net, the unconnected inputs tied as the chip pulls them (:func:`_join_global_inputs`,
:func:`_tie_unconnected`).

ECP5 (:func:`prepare_ecp5`):

The routed design is made of the chip's cells: TRELLIS_COMB (a LUT4 with its slice's wide-function
mux, a carry half or a LUT RAM half), TRELLIS_FF, TRELLIS_RAMW, DP16KD, MULT18X18D, TRELLIS_IO,
DCCA and GSR. Yosys's models (``lattice/common_sim.vh``) and ``hdl.ecp5_models`` simulate them once
the netlist says what the bitstream says (nextpnr's ``ecp5/pack.cc`` and ``bitstream.cc``):

* an input nextpnr left unconnected is a constant: a LUT's A-D are tied high (the unused inputs'
  ``*MUX`` is "1" in the bitstream; the LUT's INITVAL no longer depends on them), a carry's too;
  an FF's LSR is low (a constant low LSR is disconnected); a block RAM's or multiplier's input is
  the constant of its ``<port>MUX`` parameter: "0"/"1", or for the clock, enable, chip-select and
  reset pins of a DP16KD, which are high when unrouted, the pin's own name (1) or "INV" (0);
* an FF's data comes from M when ``SD`` is 0 (nextpnr renames DI to M when it does not pair the FF
  with the LUT that drives it), from DI when 1;
* a TRELLIS_COMB in the odd LUT of its slice (``NEXTPNR_BEL`` ``...K1``) drives OFX through the
  L6MUX (FXA, FXB), the even one through the PFUMX (F1, F): the model's ``IS_Z1``;
* a pad's unconnected data and tristate inputs are low (an output pad is driven), the IOLOGIC's
  (IOLDO, IOLTO) unused;
* the RAMW_BLOCK LUTs (placeholders beside a LUT RAM's write port, nothing connected) are removed;
* a LUT RAM's INITVAL, which nextpnr permutes into LUT-input order, is put back into address order,
  the order of the model's RAM.

Anything else (a connected pin inverted by its ``*MUX``, an LSR preload) is refused with
:class:`GateSimError` rather than simulated unchecked. (And Yosys's TRELLIS_COMB model, which never
drives its carry out, is patched by ``hdl.gatesim.cell_models``.) The routed ulx3s-system so
prepared runs a lifetime equal to the reference (docs/fpga.md).
"""

from __future__ import annotations

from base.errors import UserError


class GateSimError(UserError):
    """A netlist that cannot be made (one ``error:`` line; ``hdl.gatesim`` re-exports it)."""


_COMB_PORTS = {"A", "B", "C", "D", "M", "FCI", "F1", "FXA", "FXB", "WD", "WAD0", "WAD1", "WAD2", "WAD3", "WRE",
               "WCK", "F", "FCO", "OFX"}
_COMB_PARAMS = {"MODE", "INITVAL", "CCU2_INJECT1", "WREMUX", "IS_Z1"}
_FF_PORTS = {"CLK", "LSR", "CE", "DI", "M", "Q"}
_FF_PARAMS = {"GSR", "CEMUX", "CLKMUX", "LSRMUX", "SRMODE", "REGSET", "LSRMODE"}
# DP16KD pins on the CIB's clock, LSR and CE wires: high when unrouted (nextpnr's pack.cc)
_DP16KD_HIGH = {"CLKA", "CLKB", "RSTA", "RSTB", "WEA", "WEB", "CEA", "CEB", "OCEA", "OCEB",
                "CSA0", "CSA1", "CSA2", "CSB0", "CSB1", "CSB2"}
_KEPT_MUX = {"CLKAMUX", "CLKBMUX"}  # the DP16KD model's own
_IO_PORTS = {"B", "I", "T", "O"}


def _inputs(cell: dict) -> list[str]:
    return [port for port, direction in cell["port_directions"].items() if direction == "input"]


def _open(cell: dict, port: str) -> bool:
    return not cell["connections"].get(port)


def _tie(cell: dict, port: str, value: str) -> None:
    cell["connections"][port] = [value]


def _drop_ports(cell: dict, known: set[str], name: str) -> None:
    for port in [p for p in cell["port_directions"] if p not in known]:
        if not _open(cell, port):
            raise GateSimError(f"routed cell {name} ({cell['type']}): its port {port} is connected but not modelled")
        del cell["port_directions"][port]
        cell["connections"].pop(port, None)


def _param(cell: dict, key: str, default: str = "") -> str:
    return str(cell["parameters"].get(key, default)).strip()


def _natural_init(physical: int) -> int:
    """A LUT RAM's contents by read address, from nextpnr's INITVAL by LUT input (``dram_to_comb``:
    RAD[0..3] on D, B, C, A), as the model's RAM, read at {A, C, B, D} = RAD, holds them."""
    out = 0
    for rad in range(16):
        lut = (rad >> 3 & 1) | (rad >> 1 & 1) << 1 | (rad >> 2 & 1) << 2 | (rad & 1) << 3
        out |= (physical >> lut & 1) << rad
    return out


def _comb(name: str, cell: dict) -> None:
    mode = _param(cell, "MODE", "LOGIC")
    if mode == "DPRAM":
        cell["parameters"]["INITVAL"] = format(_natural_init(int(_param(cell, "INITVAL", "0"), 2)), "016b")
        if _param(cell, "WCKMUX", "WCK") != "WCK" or _param(cell, "WREMUX", "WRE") != "WRE":
            raise GateSimError(f"routed cell {name}: a LUT RAM with an inverted write clock or enable")
    cell["parameters"].pop("WCKMUX", None)
    if cell["attributes"].get("NEXTPNR_BEL", "").endswith("K1"):
        cell["parameters"]["IS_Z1"] = "1"
    _drop_ports(cell, _COMB_PORTS, name)
    for port in _inputs(cell):
        if _open(cell, port):
            _tie(cell, port, "1" if port in "ABCD" else "0")
    _check_params(name, cell, _COMB_PARAMS)


def _ff(name: str, cell: dict) -> None:
    if _param(cell, "LSRMODE", "LSR") != "LSR":
        raise GateSimError(f"routed cell {name}: an FF with LSRMODE {_param(cell, 'LSRMODE')} (preload)")
    sd = _param(cell, "SD", "0")
    cell["parameters"].pop("SD", None)
    if sd == "0" and not _open(cell, "M"):  # the data arrives on M (general routing)
        if not _open(cell, "DI"):
            raise GateSimError(f"routed cell {name}: an FF with both DI and M connected and SD 0")
        cell["connections"]["DI"] = cell["connections"].pop("M")
        cell["port_directions"]["DI"] = "input"
    _drop_ports(cell, _FF_PORTS, name)
    for port in _FF_PORTS - {"Q"}:
        cell["port_directions"].setdefault(port, "input")
        if _open(cell, port):
            _tie(cell, port, "0")
    _check_params(name, cell, _FF_PARAMS)


_MULT_PORTS = {f"{p}{i}" for p in "ABC" for i in range(18)} | {f"P{i}" for i in range(36)} | {
    "SIGNEDA", "SIGNEDB", "SOURCEA", "SOURCEB"}  # the model's (registers bypassed)


def _muxed(name: str, cell: dict) -> None:
    """DP16KD, MULT18X18D: each ``<port>MUX`` of an unconnected port becomes the port's constant."""
    for key in [k for k in cell["parameters"] if k.endswith("MUX") and k not in _KEPT_MUX]:
        port, value = key[:-3], _param(cell, key)
        del cell["parameters"][key]
        if port not in cell["port_directions"]:
            raise GateSimError(f"routed cell {name} ({cell['type']}): {key} names no port")
        if not _open(cell, port):
            if value != port:
                raise GateSimError(f"routed cell {name} ({cell['type']}): the connected port {port} is {value}")
            continue
        if value in ("0", "1"):
            _tie(cell, port, value)
        elif cell["type"] == "DP16KD" and port in _DP16KD_HIGH and value in (port, "INV"):
            _tie(cell, port, "1" if value == port else "0")
        else:
            raise GateSimError(f"routed cell {name} ({cell['type']}): {key} {value!r} on an unconnected port")
    if cell["type"] == "MULT18X18D":
        _drop_ports(cell, _MULT_PORTS, name)
    for port in _inputs(cell):  # never connected in synthesis (unused data bits)
        if _open(cell, port):
            if cell["type"] == "DP16KD" and not port.startswith("DI"):
                raise GateSimError(f"routed cell {name} (DP16KD): its input {port} is unconnected, with no {port}MUX")
            _tie(cell, port, "0")


def _check_params(name: str, cell: dict, known: set[str]) -> None:
    unknown = sorted(set(cell["parameters"]) - known)
    if unknown:
        raise GateSimError(f"routed cell {name} ({cell['type']}): parameter(s) {', '.join(unknown)} not modelled")


def prepare_ecp5(design: dict) -> dict:
    """``design`` (nextpnr-ecp5's ``--write`` JSON) rewritten as the module docstring says."""
    (top,) = design["modules"].values()
    cells = top["cells"]
    for name in [n for n, c in cells.items() if c["type"] == "TRELLIS_COMB" and _param(c, "MODE") == "RAMW_BLOCK"]:
        if any(cells[name]["connections"].values()):
            raise GateSimError(f"routed cell {name}: a RAMW_BLOCK LUT with connections")
        del cells[name]
    for name, cell in cells.items():
        kind = cell["type"]
        if kind == "TRELLIS_COMB":
            _comb(name, cell)
        elif kind == "TRELLIS_FF":
            _ff(name, cell)
        elif kind in ("DP16KD", "MULT18X18D"):
            _muxed(name, cell)
        elif kind == "TRELLIS_IO":  # the IOLOGIC's data and tristate (IOLDO, IOLTO): bypassed
            _drop_ports(cell, _IO_PORTS, name)
            for port in ("I", "T"):
                if _open(cell, port):
                    _tie(cell, port, "0")
        elif kind == "DCCA" and _open(cell, "CE"):
            _tie(cell, "CE", "1")
    return design


def _check_routed(design: dict, target_name: str) -> None:
    """Refuse a routed design (nextpnr's ``--write`` JSON) in which an input of a cell is left
    unconnected, constant x/z, or on a net nothing drives: the Verilator models take every input
    as it is (``_ICE40_ROUTED_VERILATOR``), where the vendor's would pull it up or down."""
    (top,) = design["modules"].values()
    driven = {b for p in top["ports"].values() if p["direction"] != "output" for b in p["bits"]}
    for cell in top["cells"].values():
        driven.update(b for port, bits in cell["connections"].items()
                      if cell["port_directions"].get(port) == "output" for b in bits)
    for name, cell in top["cells"].items():
        for port, direction in cell["port_directions"].items():
            bits = cell["connections"].get(port)
            if direction == "input" and (not bits or any(b in ("x", "z") or (isinstance(b, int) and b not in driven)
                                                             for b in bits)):
                raise GateSimError(f"{target_name}: the routed cell {name} ({cell['type']}) has its input {port} "
                                   f"undriven; the routed netlist cannot be simulated with the models as read")


def _join_global_inputs(design: dict, target_name: str) -> dict:
    """``design`` with each clock pin's path into its global buffer made a net.

    An iCE40 clock pin (a GBIN pad) reaches its global buffer by a dedicated wire that nextpnr's
    ``--write`` leaves implicit: the SB_IO's ``GLOBAL_BUFFER_OUTPUT`` and the SB_GB
    ``$gbuf_<pad>_io``'s input are both empty. The SB_GB gets the pad's pin as its input."""
    (top,) = design["modules"].values()
    cells = top["cells"]
    for name, cell in cells.items():
        if cell["type"] == "SB_IO" and cell["connections"].get("GLOBAL_BUFFER_OUTPUT") == []:
            buffer = cells.get(f"$gbuf_{name}_io")
            if buffer is None or buffer["connections"].get("USER_SIGNAL_TO_GLOBAL_BUFFER") != []:
                raise GateSimError(f"{target_name}: the routed pad {name} feeds a global buffer that is "
                                   f"not $gbuf_{name}_io with its input empty")
            buffer["connections"]["USER_SIGNAL_TO_GLOBAL_BUFFER"] = list(cell["connections"]["PACKAGE_PIN"])
            del cell["connections"]["GLOBAL_BUFFER_OUTPUT"]
            del cell["port_directions"]["GLOBAL_BUFFER_OUTPUT"]
    return design


# What an unconnected input of a routed iCE40 cell is on the chip (the models' pull-ups and
# pull-downs): 1 for the clock enables, 0 for the rest.
_ICE40_PULLED = {"ICESTORM_LC", "ICESTORM_RAM", "SB_IO"}
_ICE40_PULLED_UP = {"CEN", "RCLKE", "WCLKE", "CLOCK_ENABLE"}


def _tie_unconnected(design: dict) -> dict:
    """``design`` with every unconnected input of an iCE40 logic, RAM or I/O cell tied to the
    value the chip (and the vendor model's ``=== 1'bz`` test) gives it, so that the Verilator
    copies of the models, which take every input as it is, simulate the same logic."""
    (top,) = design["modules"].values()
    for cell in top["cells"].values():
        if cell["type"] in _ICE40_PULLED:
            for port, direction in cell["port_directions"].items():
                if direction == "input" and not cell["connections"].get(port):
                    cell["connections"][port] = ["1" if port in _ICE40_PULLED_UP else "0"]
    return design


def prepare(design: dict, family: str, target_name: str) -> dict:
    """``design`` as the cell models of ``family`` simulate it, every input driven (or refused)."""
    design = prepare_ecp5(design) if family == "ecp5" else _tie_unconnected(_join_global_inputs(design, target_name))
    _check_routed(design, target_name)
    return design


__all__ = ["GateSimError", "prepare", "prepare_ecp5"]

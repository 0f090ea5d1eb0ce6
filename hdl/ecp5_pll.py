"""The ECP5 PLL (EHXPLLL) that clocks a board top faster than the board's oscillator.

A bitstream target with ``Target.pll_hz`` (``hdl.fpga``) runs its ``sync`` domain at the PLL's
CLKOP instead of the oscillator: :func:`add_pll_domain` replaces the platform's default ``sync``
domain (amaranth's ``LatticePlatform.create_missing_domain``) with the same reset scheme on the
PLL's clock. The fabric is held in reset by the global set/reset (SGSR, active low) until the
PLL is locked: LOCK goes through two flip-flops on CLKOP into SGSR, as amaranth's own domain does
with its reset pin. nextpnr derives CLKOP's frequency from the dividers and the oscillator pin's
constraint ("Derived frequency constraint of 30.0 MHz for net clk"), so its timing report says
whether the routed design meets the clock it runs at, and ``hdl.fpga`` finds no clock at the
frequency asked if the dividers made another. (A constraint on the PLL's output net by name would
be lost: Yosys merges it into the ``sync`` clock's net.)

:func:`pll_params` chooses the dividers as Lattice's ``ecppll`` does for one output fed back
from CLKOP: f_out = f_in / CLKI_DIV * CLKFB_DIV exactly, the phase detector's input f_in / CLKI_DIV
in 3.125..400 MHz, the VCO f_out * CLKOP_DIV in 400..800 MHz (Lattice FPGA-TN-02200, "ECP5 and
ECP5-5G sysCLOCK PLL/DLL Design and User Guide"), CLKOP_CPHASE = ceil(CLKOP_DIV / 2) - 1 (ecppll's
0-degree phase), and the loop-filter attributes ecppll writes for it.

For gate-level simulation (``hdl.gatesim``) the EHXPLLL model of ``hdl.ecp5_models`` passes CLKI
to CLKOP and raises LOCK after a few cycles: the harness drives the clock pin at the PLL's output
frequency, so the simulated cycles are the chip's.
"""

from __future__ import annotations

from fractions import Fraction

from amaranth.hdl import ClockDomain, ClockSignal, Const, Instance, Module, Signal
from amaranth.lib import io

PFD_MHZ = (3.125, 400.0)
VCO_MHZ = (400.0, 800.0)
# the loop filter's attributes as Lattice's ecppll writes them (nextpnr-ecp5 packs them as given)
LOOP_FILTER = {"ICP_CURRENT": "12", "LPF_RESISTOR": "8", "MFG_ENABLE_FILTEROPAMP": "1", "MFG_GMCREF_SEL": "2"}


class PLLError(ValueError):
    """No divider setting gives the frequency asked exactly."""


def pll_params(in_hz: float, out_hz: float) -> dict[str, int]:
    """EHXPLLL's dividers for ``out_hz`` on CLKOP from ``in_hz`` on CLKI (the module docstring):
    ``CLKI_DIV``, ``CLKFB_DIV``, ``CLKOP_DIV``, ``CLKOP_CPHASE``. The VCO closest to 600 MHz (the
    middle of its range) among the exact settings; ``PLLError`` if there is none."""
    ratio = Fraction(round(out_hz), 1) / Fraction(round(in_hz), 1)
    best = None
    for clki_div in range(1, 129):
        pfd_mhz = in_hz / clki_div / 1e6
        if not PFD_MHZ[0] <= pfd_mhz <= PFD_MHZ[1]:
            continue
        clkfb = ratio * clki_div
        if clkfb.denominator != 1 or not 1 <= clkfb.numerator <= 80:
            continue
        for clkop_div in range(1, 129):
            vco_mhz = out_hz * clkop_div / 1e6
            if VCO_MHZ[0] <= vco_mhz <= VCO_MHZ[1]:
                key = abs(vco_mhz - 600.0)
                if best is None or key < best[0]:
                    best = (key, clki_div, clkfb.numerator, clkop_div)
    if best is None:
        raise PLLError(f"the ECP5 PLL cannot make exactly {out_hz / 1e6:g} MHz from {in_hz / 1e6:g} MHz")
    _, clki_div, clkfb_div, clkop_div = best
    return {"CLKI_DIV": clki_div, "CLKFB_DIV": clkfb_div, "CLKOP_DIV": clkop_div,
            "CLKOP_CPHASE": (clkop_div + 1) // 2 - 1}


def add_pll_domain(m: Module, platform, out_hz: float) -> Signal:
    """Add to ``m`` the ``sync`` domain at ``out_hz`` from the platform's default clock through an
    EHXPLLL, held in reset until the PLL locks (see the module docstring); returns LOCK. The domain
    is defined in ``m`` itself, the top (amaranth 0.6 will want a domain defined where it is used
    or above)."""
    in_hz = float(platform.default_clk_frequency)
    params = pll_params(in_hz, out_hz)
    clk_io = platform.request(platform.default_clk, dir="-")
    m.submodules.clk_buf = clk_buf = io.Buffer("i", clk_io)
    clk_out, lock = Signal(name="pll_clk"), Signal(name="pll_lock")
    m.submodules.pll = Instance(
        "EHXPLLL",
        **{f"a_{k}": v for k, v in LOOP_FILTER.items()},
        a_FREQUENCY_PIN_CLKI=f"{in_hz / 1e6:g}", a_FREQUENCY_PIN_CLKOP=f"{out_hz / 1e6:g}",
        p_PLLRST_ENA="DISABLED", p_INTFB_WAKE="DISABLED", p_STDBY_ENABLE="DISABLED",
        p_DPHASE_SOURCE="DISABLED", p_OUTDIVIDER_MUXA="DIVA", p_OUTDIVIDER_MUXB="DIVB",
        p_OUTDIVIDER_MUXC="DIVC", p_OUTDIVIDER_MUXD="DIVD", p_CLKOP_ENABLE="ENABLED",
        p_CLKOP_FPHASE=0, p_FEEDBK_PATH="CLKOP", **{f"p_{k}": v for k, v in params.items()},
        i_CLKI=clk_buf.i, i_CLKFB=clk_out, o_CLKOP=clk_out, o_LOCK=lock,
        i_RST=Const(0), i_STDBY=Const(0), i_PHASESEL0=Const(0), i_PHASESEL1=Const(0),
        i_PHASEDIR=Const(1), i_PHASESTEP=Const(1), i_PHASELOADREG=Const(1),
        i_PLLWAKESYNC=Const(0), i_ENCLKOP=Const(0),
    )
    gsr0, gsr1 = Signal(), Signal()
    m.submodules += [
        Instance("FD1S3AX", p_GSR="DISABLED", i_CK=clk_out, i_D=lock, o_Q=gsr0),
        Instance("FD1S3AX", p_GSR="DISABLED", i_CK=clk_out, i_D=gsr0, o_Q=gsr1),
        Instance("SGSR", i_CLK=clk_out, i_GSR=gsr1),
    ]
    # as amaranth's own sync domain: GSR resets every flip-flop, so the domain has no reset
    m.domains.sync = ClockDomain("sync", reset_less=True)
    m.d.comb += ClockSignal("sync").eq(clk_out)
    return lock

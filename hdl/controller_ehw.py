"""The robot's controller board (SPEC section 8): shadow/active configuration, reflex, AND-OR array.

Timing plan (one clock domain, ``sync``, synchronous reset):

- Row write: with ``row.we`` high during cycle t, ``row.data`` replaces row ``row.addr`` of the
  *shadow* configuration at the clock edge that ends cycle t. Addresses >= k are ignored. The
  shadow never drives the array.
- Commit: with ``commit`` high during cycle t, the shadow (including a row written in the same
  cycle t: the write is part of the commit) is copied into the *active* configuration at the edge
  that ends cycle t. The copy is one register transfer of all k rows, so the array sees either
  the old controller or the new one, never a mixture: a half-loaded shadow cannot reach
  ``motion``. The shadow keeps its contents, so a host may rewrite only the rows that changed and
  commit again.
- Motion: registered. ``motion`` during cycle t + 1 is the motion for the ``x`` and
  ``reflex_en`` presented during cycle t, under the active configuration of cycle t (1 cycle of
  latency). Hence a commit in cycle t shows in ``motion`` from cycle t + 2.
- Reset (synchronous, ``rst`` of the domain): shadow and active configurations are all zero
  (every row empty and driving nothing: the array outputs 0, forward) and ``motion`` is 0.

The reflex of SPEC section 6 sits in front of the array: when ``reflex_en`` is high and no
obstacle bit is set, the motion is the fixed reflex motion of the target sector.
"""

from __future__ import annotations

from amaranth.hdl import Module, Signal
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out

from ga.genome import N_ROWS, ROW_BITS
from ga.motions import N_INPUTS, N_OUTPUTS, OBSTACLE_MASK, REFLEX_MOTION, SECTOR_SHIFT
from hdl.and_or_array import AndOrArray, _check_positive
from hdl.ports import RowWriteSignature, row_addr_bits  # noqa: F401  (row_addr_bits: re-export)


class ControllerEHW(wiring.Component):
    """The robot's EHW board: an AND-OR array behind a double-buffered configuration and a reflex.

    Parameters
    ----------
    k : int
        Rows of the AND-OR array (default 50, SPEC section 3). n = 8 and m = 3 are fixed by the
        sensor and motion contract of SPEC section 4.

    Ports
    -----
    row : In(RowWriteSignature(k))
        Row-write port (``hdl.ports``): ``row.we`` writes the row word ``row.data`` (SPEC section 3:
        bit 2i x_i, 2i + 1 NOT x_i, 16 + j drives y_j) into shadow row ``row.addr`` (0..k-1;
        larger addresses are ignored) at the next clock edge. Verilog: ``row__addr`` [5:0],
        ``row__data`` [18:0], ``row__we``.
    commit : In(1)
        Copy the shadow (with this cycle's write, if any) into the active configuration at the
        next clock edge.
    x : In(8)
        World state (sensor bits x0..x7).
    reflex_en : In(1)
        Put the reflex in front of the array (SPEC section 6).
    motion : Out(3)
        Registered motion code: the motion for the previous cycle's ``x`` (1 cycle latency).
    """

    def __init__(self, k: int = N_ROWS):
        self.k = _check_positive("k", k)
        self.n = N_INPUTS
        self.m = N_OUTPUTS
        self.row_bits = ROW_BITS
        assert ROW_BITS == 2 * N_INPUTS + N_OUTPUTS
        super().__init__({
            "row": In(RowWriteSignature(k)),
            "commit": In(1),
            "x": In(N_INPUTS),
            "reflex_en": In(1),
            "motion": Out(N_OUTPUTS),
        })

    def elaborate(self, platform):
        m = Module()
        k, W = self.k, self.row_bits
        array = m.submodules.array = AndOrArray(n=self.n, m=self.m, k=k)

        # Configuration: the shadow is filled row by row; the active one drives the array.
        shadow = Signal(k * W)
        active = Signal(k * W)
        shadow_next = Signal(k * W)  # the shadow after this cycle's write: what a commit takes
        m.d.comb += shadow_next.eq(shadow)
        for r in range(k):
            write_r = self.row.we & (self.row.addr == r)
            with m.If(write_r):
                m.d.comb += shadow_next[r * W:(r + 1) * W].eq(self.row.data)
        m.d.sync += shadow.eq(shadow_next)
        with m.If(self.commit):
            m.d.sync += active.eq(shadow_next)

        m.d.comb += [
            array.arch.eq(active),
            array.x.eq(self.x),
        ]

        # Reflex (SPEC section 6): no obstacle bit set -> the fixed motion of the target sector.
        # The table comes from ga.motions, the single source of truth for it.
        no_obstacle = (self.x & OBSTACLE_MASK) == 0
        sector = self.x[SECTOR_SHIFT:]
        assert len(REFLEX_MOTION) == 1 << len(sector)
        reflex_motion = Signal(self.m)
        with m.Switch(sector):
            for code, motion in enumerate(REFLEX_MOTION):
                with m.Case(code):
                    m.d.comb += reflex_motion.eq(int(motion))
        use_reflex = self.reflex_en & no_obstacle

        with m.If(use_reflex):
            m.d.sync += self.motion.eq(reflex_motion)
        with m.Else():
            m.d.sync += self.motion.eq(array.y)
        return m

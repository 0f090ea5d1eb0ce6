"""The AND-OR array of the EHW boards: a combinational PLA whose personality is the genome.

SPEC section 3 (normative): row r of k occupies architecture bits [W r, W r + W), W = 2n + m.
Inside a row, bit 2i connects literal x_i to the row's AND, bit 2i + 1 connects NOT x_i, and bit
2n + j makes the row drive output y_j. A row fires when every connected literal is true, so a row
with no literal fires always (as in a real PLA) and a row holding both x_i and NOT x_i never fires.
y_j is the OR of the firing rows that drive j; no row firing gives y = 0.
"""

from __future__ import annotations

from amaranth.hdl import Cat, Module, Signal
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out


def _check_positive(name: str, value) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        raise TypeError(f"{name} must be a positive integer, got {value!r}")
    if value < 1:
        raise ValueError(f"{name} must be a positive integer, got {value!r}")
    return value


class AndOrArray(wiring.Component):
    """Combinational AND-OR array with ``n`` inputs, ``m`` outputs and ``k`` rows.

    Parameters
    ----------
    n, m, k : int
        Inputs, outputs and rows (the paper's board: 8, 3, 50). Each must be a positive integer.

    Ports
    -----
    arch : In(k * (2n + m))
        The architecture bits (the genome), row r in bits [W r, W r + W), W = 2n + m.
    x : In(n)
        The input bits (world state).
    y : Out(m)
        The output bits (motion code), combinational: no register, no clock.
    """

    def __init__(self, n: int = 8, m: int = 3, k: int = 50):
        self.n = _check_positive("n", n)
        self.m = _check_positive("m", m)
        self.k = _check_positive("k", k)
        self.row_bits = 2 * n + m
        super().__init__({
            "arch": In(self.k * self.row_bits),
            "x": In(self.n),
            "y": Out(self.m),
        })

    def row(self, r: int):
        """The ``row_bits``-wide slice of ``arch`` that holds row ``r``."""
        return self.arch[r * self.row_bits:(r + 1) * self.row_bits]

    def elaborate(self, platform):
        m = Module()
        n, W = self.n, self.row_bits

        # A connected literal that is false at the current x blocks its row. Literal 2i (x_i) is
        # false when x_i = 0, literal 2i + 1 (NOT x_i) when x_i = 1: interleave ~x_i and x_i.
        false_literals = Signal(2 * n)
        m.d.comb += false_literals.eq(Cat(*((~self.x[i], self.x[i]) for i in range(n))))

        fires = Signal(self.k)
        for r in range(self.k):
            literals = self.row(r)[:2 * n]
            # Empty rows fire (nothing blocks them); x_i with NOT x_i never fires (one is false).
            m.d.comb += fires[r].eq((literals & false_literals) == 0)

        for j in range(self.m):
            drives_j = Cat(self.row(r)[2 * n + j] for r in range(self.k))
            m.d.comb += self.y[j].eq((fires & drives_j).any())
        return m

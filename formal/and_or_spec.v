// The AND-OR array of SPEC section 3, written from the spec text alone (not from hdl/), as the
// reference the generated and_or_array.v is proven equal to (formal/proofs.py, proof and_or_array).
//
// SPEC section 3: n inputs, m outputs, k rows of 2n + m bits; row r occupies arch[W r +: W],
// W = 2n + m. Inside a row, bit 2i connects the literal x_i to the row's AND, bit 2i + 1 connects
// NOT x_i, bit 2n + j makes the row drive y_j. A row fires when every connected literal is true (a
// row with no connected literal fires always; x_i together with NOT x_i never fires). y_j is the
// OR of the firing rows that drive j; no row firing gives y = 0.
module and_or_spec #(
    parameter N = 8,
    parameter M = 3,
    parameter K = 50
) (
    input  wire [K*(2*N+M)-1:0] arch,
    input  wire [N-1:0]         x,
    output wire [M-1:0]         y
);
    localparam W = 2 * N + M;
    wire [K-1:0] fires;
    genvar r, i, j;
    generate
        for (r = 0; r < K; r = r + 1) begin : row
            wire [N-1:0] lit_x;     // bit 2i: x_i is connected
            wire [N-1:0] lit_not_x; // bit 2i + 1: NOT x_i is connected
            for (i = 0; i < N; i = i + 1) begin : literal
                assign lit_x[i]     = arch[r*W + 2*i];
                assign lit_not_x[i] = arch[r*W + 2*i + 1];
            end
            // Fires when no connected literal is false: x_i connected needs x_i = 1, NOT x_i
            // connected needs x_i = 0. No connected literal: nothing can block, it fires.
            assign fires[r] = ~|((lit_x & ~x) | (lit_not_x & x));
        end
        for (j = 0; j < M; j = j + 1) begin : out
            wire [K-1:0] drives;    // row r drives y_j: bit 2n + j of row r
            for (r = 0; r < K; r = r + 1) begin : row
                assign drives[r] = arch[r*W + 2*N + j];
            end
            assign y[j] = |(fires & drives);
        end
    endgenerate
endmodule

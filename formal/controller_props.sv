// Properties of ControllerEHW (hdl/controller_ehw.py), proven by temporal induction
// (formal/proofs.py, proof controller_ehw). The harness drives every input of the board freely;
// the only assumption is a reset in the first cycle (the solver's base case), after which any
// sequence of row writes, commits, sensor bits, reflex enables and further resets is allowed.
//
// The model below is the board's documented behaviour (module docstring), written independently:
// m_shadow / m_active follow the row-write port and the commit strobe, and m_motion is the
// motion SPEC sections 3 and 6 give for last cycle's x under last cycle's active configuration.
`include "dut_ports.vh"

module controller_props #(
    parameter K = 50,  // rows (ControllerEHW(k))
    parameter A = 6    // row address bits (hdl.controller_ehw.row_addr_bits(k))
) (
    input wire        clk,
    input wire        rst,
    input wire [A-1:0] row_addr,
    input wire [18:0] row_data,
    input wire        row_we,
    input wire        commit,
    input wire [7:0]  x,
    input wire        reflex_en
);
    localparam W = 19;

    wire [2:0] motion;
    controller_ehw dut (`DUT_PORTS);

    // The DUT's internal registers, connected by formal/ports.py after flatten (probes).
    (* keep *) wire [K*W-1:0] probe_active;
    (* keep *) wire [K*W-1:0] probe_shadow;

    // -- the documented behaviour -------------------------------------------------------------
    reg [K*W-1:0] m_shadow, m_active;
    reg [2:0]     m_motion;
    reg [K*W-1:0] m_shadow_next;  // the shadow with this cycle's row write (what a commit takes)
    always @* begin
        m_shadow_next = m_shadow;
        if (row_we && row_addr < K)
            m_shadow_next[row_addr*W +: W] = row_data;
    end

    wire [2:0] array_y, reflex_y;
    wire       use_reflex;
    and_or_spec #(.N(8), .M(3), .K(K)) spec_array (.arch(m_active), .x(x), .y(array_y));
    reflex_spec spec_reflex (.x(x), .enable(reflex_en), .active(use_reflex), .motion(reflex_y));

    always @(posedge clk) begin
        if (rst) begin  // documented reset: both configurations empty, motion 0 (forward)
            m_shadow <= 0;
            m_active <= 0;
            m_motion <= 0;
        end else begin
            m_shadow <= m_shadow_next;
            if (commit)
                m_active <= m_shadow_next;
            m_motion <= use_reflex ? reflex_y : array_y;
        end
    end

    // -- last cycle's inputs and DUT state, for the transition properties ----------------------
    reg           rst_q, commit_q, row_we_q;
    reg [K*W-1:0] active_q;
    always @(posedge clk) begin
        rst_q    <= rst;
        commit_q <= commit;
        row_we_q <= row_we;
        active_q <= probe_active;
    end

    always @* begin
        // (1) motion: the array's (or the reflex's) output for the active configuration and x of
        //     the previous cycle.
        assert (motion == m_motion);
        // (2) the DUT's configuration registers are the documented ones (also the induction
        //     invariant: the model and the DUT agree on everything that is not yet visible).
        assert (probe_active == m_active);
        assert (probe_shadow == m_shadow);
        // (3) the active configuration changes only at a commit, and then equals the shadow.
        if (!rst_q && !commit_q)
            assert (probe_active == active_q);
        if (!rst_q && commit_q)
            assert (probe_active == probe_shadow);
        // (4) a row write without a commit leaves the active configuration, hence the output
        //     function, unchanged.
        if (!rst_q && row_we_q && !commit_q)
            assert (probe_active == active_q);
        // (5) reset gives the documented configuration: everything empty, motion 0.
        if (rst_q)
            assert (motion == 3'd0 && probe_active == 0 && probe_shadow == 0);
    end
endmodule

// Properties of the host link's frame decoder, hdl.link_protocol.FrameReceiver (formal/proofs.py, proof
// link_decoder), by temporal induction. The harness feeds it any byte stream (valid and payload
// free in every cycle); the base case is a reset in the first cycle.
//
// The model below is the frame format of hdl/link_protocol.py's docstring, written independently:
// SYNC (0xA5) | command | status | tag | length | payload[length] | crc[15:8] | crc[7:0] (H = 4
// header bytes, the last one the payload length), the CRC being
// CRC-16/IBM-3740 ("CCITT-FALSE": poly 0x1021, init 0xFFFF, not reflected, no final XOR) over the
// header and payload, computed here bit by bit and compared with the received bytes (the decoder
// instead checks the residue of its CRC register over the whole frame). A frame with no byte for
// T cycles is dropped. Cycle timing as the decoder documents it: the verdict (done, ok) or the
// drop (truncated) is a one-cycle pulse.
`include "dut.vh"

module link_props #(
    parameter T = 4,    // FrameReceiver(timeout_cycles=T)
    parameter H = 4     // header bytes (hdl.link_protocol.HEADER_BYTES); the last one is the length
) (
    input wire       clk,
    input wire       rst,
    input wire       valid,
    input wire [7:0] payload
);
    localparam SB = $clog2(T + 1);  // width of the decoder's silence counter
    localparam [2:0] M_SYNC = 0, M_HEADER = 1, M_PAYLOAD = 2, M_CRC = 3, M_CHECK = 4;

    wire        ready, done, ok, truncated;
    wire [8*H-1:0] header;
    frame_receiver dut (`DUT_PORTS);

    (* keep *) wire [2:0]    probe_fsm;
    (* keep *) wire [7:0]    probe_position;
    (* keep *) wire [SB-1:0] probe_silent;
    (* keep *) wire [15:0]   probe_crc;

    function [15:0] crc_byte(input [15:0] c, input [7:0] b);
        integer i;
        reg [15:0] r;
        begin
            r = c ^ {b, 8'h00};
            for (i = 0; i < 8; i = i + 1)
                r = r[15] ? ((r << 1) ^ 16'h1021) : (r << 1);
            crc_byte = r;
        end
    endfunction

    // -- the frame format (model) --------------------------------------------------------------
    reg [2:0]    ms;
    reg [7:0]    mpos, mlen;
    reg [8*H-1:0] mheader;    // the header bytes, the first in the low byte
    reg [SB-1:0] msilent;
    reg [15:0]   mcrc;        // CRC of header + payload so far
    reg [15:0]   mrx;         // the CRC bytes received
    reg          m_done, m_ok, m_truncated;
    reg [7:0]    quiet;       // cycles since the last byte (saturates)
    wire in_frame = ms == M_HEADER || ms == M_PAYLOAD || ms == M_CRC;
    wire stalled = in_frame && msilent == T;

    always @(posedge clk) begin
        if (rst) begin
            ms <= M_SYNC;
            mpos <= 0;
            msilent <= 0;
            m_done <= 0;
            m_truncated <= 0;
            quiet <= 0;
        end else begin
            m_done <= 0;
            m_truncated <= 0;
            msilent <= (valid || !in_frame) ? 0 : msilent + 1;
            quiet <= valid ? 0 : (quiet == 8'hff ? quiet : quiet + 1);
            case (ms)
                M_SYNC:
                    if (valid && payload == 8'hA5) begin
                        ms <= M_HEADER;
                        mpos <= 0;
                        mcrc <= 16'hFFFF;
                    end
                M_HEADER:
                    if (stalled) begin
                        m_truncated <= 1;
                        ms <= M_SYNC;
                    end else if (valid) begin
                        mcrc <= crc_byte(mcrc, payload);
                        mheader[mpos*8 +: 8] <= payload;
                        mpos <= mpos + 1;
                        if (mpos == H - 1) begin
                            mlen <= payload;
                            mpos <= 0;
                            ms <= payload == 0 ? M_CRC : M_PAYLOAD;
                        end
                    end
                M_PAYLOAD:
                    if (stalled) begin
                        m_truncated <= 1;
                        ms <= M_SYNC;
                    end else if (valid) begin
                        mcrc <= crc_byte(mcrc, payload);
                        mpos <= mpos + 1;
                        if (mpos == mlen - 1) begin
                            mpos <= 0;
                            ms <= M_CRC;
                        end
                    end
                M_CRC:
                    if (stalled) begin
                        m_truncated <= 1;
                        ms <= M_SYNC;
                    end else if (valid) begin
                        mrx <= {mrx[7:0], payload};
                        mpos <= mpos + 1;
                        if (mpos == 1)
                            ms <= M_CHECK;
                    end
                default: begin  // M_CHECK: the verdict
                    m_done <= 1;
                    m_ok <= mrx == mcrc;
                    ms <= M_SYNC;
                end
            endcase
        end
    end

    // the decoder's FSM state for each model state
    reg [2:0] expected_fsm;
    always @* begin
        case (ms)
            M_SYNC:    expected_fsm = `FSM_SYNC;
            M_HEADER:  expected_fsm = `FSM_HEADER;
            M_PAYLOAD: expected_fsm = `FSM_PAYLOAD;
            M_CRC:     expected_fsm = `FSM_CRC;
            default:   expected_fsm = `FSM_CHECK;
        endcase
    end

    always @* begin
        assert (ready);  // bytes are always taken
        // (1) a frame is executed (done with ok) only when it is complete and its CRC matches the
        //     received bytes, and then the header the dispatcher reads is the frame's.
        assert (done == m_done && truncated == m_truncated);
        if (done)
            assert (ok == m_ok && header == mheader);
        // (2) every other frame that began gets a verdict: done without ok (a CRC error) or
        //     truncated (stalled); there is no third way out of a frame (the model has none).
        // (3) back to idle after any byte sequence: at most T + 1 quiet cycles inside a frame.
        if (quiet > T + 1)
            assert (probe_fsm == `FSM_SYNC);
        // the decoder's state is the model's (the induction invariant)
        assert (ms <= M_CHECK && probe_fsm == expected_fsm);
        if (in_frame)
            assert (probe_position == mpos && probe_silent == msilent && msilent <= T
                    && quiet == msilent);
        if (ms == M_CHECK)
            assert (quiet == 0);
        if (ms == M_HEADER || ms == M_PAYLOAD)
            assert (probe_crc == mcrc);
        if (ms == M_HEADER)  // the header bytes received so far are the decoder's
            assert (mpos <= H - 1 && ((header ^ mheader) & ((1 << (8 * mpos)) - 1)) == 0);
        if (ms == M_PAYLOAD)
            assert (mpos < mlen && mlen == mheader[8*H-1 -: 8] && header == mheader);
        if (ms == M_CRC)
            assert (mpos <= 1 && header == mheader
                    && probe_crc == (mpos == 0 ? mcrc : crc_byte(mcrc, mrx[7:0])));
        if (ms == M_CHECK)
            assert (header == mheader && probe_crc == crc_byte(crc_byte(mcrc, mrx[15:8]), mrx[7:0]));
    end
endmodule

"""A link that survives a real cable (issue 39): seeded line faults, the host's detection and
recovery, a whole lifetime over a noisy line equal to the clean one, a dead line that stops with
one error line and a checkpoint, and the host decoder under random corrupted streams."""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import one_error
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from base.errors import UserError
from cosim.link.emulated import EmulatedLine
from cosim.link.faults import FaultyLine, LineFaults, parse_faults
from cosim.link.host import LinkClient, LinkError, crc16, encode_frame, pack
from hdl.link_protocol import (
    LINK_CRC,
    MOTION_REPLY,
    MOTION_REQUEST,
    SYNC,
    Command,
    Status,
)

LIFETIME = ["--targets", "4", "--population", "20", "--quiet", "--no-plots"]
FAULTS = "flip=1e-4,drop=1e-4,silence=1e-3,reset=3,seed=2"
# what differs between a backend and the reference's summary by design (docs/host_link.md)
NOT_COMPARED = {"backend", "wall_time_s", "board_cycles", "hardware", "line_faults"}


def _same_lifetime(a, b):
    """Two run folders: the same summary (but the keys that name the backend and its time) and
    the same motions, in order, up to the last checkpoint (its replay log)."""
    sa, sb = (json.loads((d / "summary.json").read_text()) for d in (a, b))
    assert {k: v for k, v in sa.items() if k not in NOT_COMPARED} == \
           {k: v for k, v in sb.items() if k not in NOT_COMPARED}
    ma, mb = (json.loads((d / "checkpoint.json").read_text())["state"]["motions"] for d in (a, b))
    assert ma == mb and 0 < len(bytes.fromhex(ma)) <= sa["interactions"]  # hex, a byte a motion


# -- the pieces ------------------------------------------------------------------------------------


def test_the_fast_crc_is_the_catalogue_entry():
    rng = np.random.default_rng(39)
    for n in (0, 1, 4, 7, 128, 259):
        body = rng.integers(0, 256, n, dtype=np.uint8).tobytes()
        assert crc16(body) == LINK_CRC.compute(body)
        assert crc16(body + crc16(body).to_bytes(2, "big")) == LINK_CRC.residue() == 0


@pytest.mark.parametrize("text, words", [
    ("flip=2", "flip"), ("drop=-0.1", "drop"), ("reset=x", "reset"), ("noise=0.1", "noise"),
    ("flip=0.1,flip=0.2", "twice"), ("silence", "KEY=VALUE"), ("reset=5000", "reset")])
def test_a_bad_fault_spec_is_a_user_error(text, words):
    with pytest.raises(UserError, match=words):
        parse_faults(text)


def test_faults_are_seeded_and_counted():
    spec = LineFaults(flip=0.01, drop=0.01, silence=0.05, reset=2, reset_from=2, reset_within=50, seed=7)

    def traffic():
        line = FaultyLine(EmulatedLine(), spec)
        client = LinkClient(line)
        replies = []
        for state in range(60):
            try:
                replies.append(client.request(Command.MOTION, pack(MOTION_REQUEST, state=state)))
            except LinkError as exc:
                replies.append(str(exc))
        return line.injected, replies

    first, again = traffic(), traffic()
    assert first == again
    assert first[0]["reset"] == 2 and first[0]["flip"] > 0 and first[0]["drop"] > 0


def test_the_emulated_board_answers_errors_as_the_gateware():
    line = EmulatedLine()
    frame = encode_frame(Command.MOTION, b"\x05", tag=9)
    line.write(frame[:-1] + bytes([frame[-1] ^ 1]))  # a bad CRC
    assert line.read(64)[:4] == bytes([SYNC, Command.MOTION.value, Status.BAD_CRC.value, 9])
    line.write(frame[:4])  # a frame that stalls: the inter-byte timeout
    assert line.read(64)[:3] == bytes([SYNC, Command.MOTION.value, Status.TRUNCATED.value])
    line.write(encode_frame(Command.LEARN, b"\0" * 4, tag=3))  # the learner's command
    assert line.read(64)[2] == Status.UNKNOWN_COMMAND.value
    line.write(encode_frame(Command.MOTION, b"\0\0", tag=4))
    assert line.read(64)[2] == Status.BAD_LENGTH.value


def test_a_reset_is_detected_and_the_board_restored():
    """A reset between two requests that loses the next frame: the host sees the board's frame
    count go back, restores the controller and world model from its mirror, and the request
    that follows gets the answer it would have got."""
    from cosim.link.boards import boards_over

    line = EmulatedLine()
    client = LinkClient(line)
    controller, evaluator = boards_over([client])
    rows = np.arange(50, dtype=np.uint32) * 977 % (1 << 19)
    controller.load(rows)
    evaluator.observe(3, 1, 4, False)
    evaluator.observe(4, 2, 4, True)
    evaluator.write_rates([(3, 1, 60)])
    before = evaluator.evaluate(np.stack([rows, rows[::-1]]))
    line.board_reset()
    line.write(b"\xa5")  # the frame in flight is lost: an unfinished frame, then nothing
    wanted = [controller.reference.motion(s) for s in range(256)]
    assert [controller.motion(s) for s in range(256)] == wanted
    after = evaluator.evaluate(np.stack([rows, rows[::-1]]))
    assert client.stats.resets == 1 and client.stats.restores == 1
    assert line.board.model.n_states == evaluator.model.n_states == 2
    assert np.array_equal(after.distance, before.distance) and np.array_equal(after.fails, before.fails)


# -- the host decoder under random corrupted streams (Hypothesis) ------------------------------------


class _ScriptedStream:
    """Answers each request frame with the next of ``replies`` (bytes), then nothing."""

    port = "scripted"

    def __init__(self, replies):
        self.replies, self.buffer, self.writes = list(replies), bytearray(), 0

    def write(self, data):
        self.writes += 1
        if self.replies:
            self.buffer += self.replies.pop(0)
        return len(data)

    def read(self, n):
        out = bytes(self.buffer[:n])
        del self.buffer[:n]
        return out

    def reset_input_buffer(self):
        self.buffer.clear()


def _corrupt(frame: bytes, how) -> bytes:
    kind, a, b = how
    data = bytearray(frame)
    if kind == "flip":  # up to 3 bits: CRC-16/IBM-3740 detects them all in frames this short
        for bit in {a % (8 * len(data)), b % (8 * len(data)), (a + b) % (8 * len(data))}:
            data[bit // 8] ^= 1 << (bit % 8)
    elif kind == "burst":  # a burst of up to 16 bits: detected too
        start = a % (8 * len(data))
        for bit in range(start, min(start + 1 + b % 16, 8 * len(data))):
            data[bit // 8] ^= 1 << (bit % 8)
    elif kind == "drop":
        del data[a % len(data)]
    elif kind == "truncate":
        del data[a % len(data):]
    elif kind == "garbage":
        data[0:0] = bytes([a % 256, b % 256, SYNC, (a * 7) % 256])
    return bytes(data)


HOW = st.tuples(st.sampled_from(["flip", "burst", "drop", "truncate", "garbage", "none"]),
                st.integers(0, 10_000), st.integers(0, 10_000))


@settings(max_examples=150, deadline=2000, suppress_health_check=[HealthCheck.too_slow])
@given(hows=st.lists(HOW, min_size=0, max_size=6), noise=st.binary(max_size=40))
def test_the_decoder_never_hangs_nor_takes_a_corrupted_frame(hows, noise):
    """Each try of a MOTION request is answered by a damaged copy of the right reply (tag 1, 2,
    ... as the client counts them) or noise: the client returns the true motion or raises
    LinkError; never another exception, never a wrong motion, in a bounded number of reads."""
    motion = 5
    payload = pack(MOTION_REPLY, motion=motion)
    replies = [noise + _corrupt(encode_frame(Command.MOTION, payload, tag=i + 1, status=Status.OK), how)
               for i, how in enumerate(hows)]
    stream = _ScriptedStream(replies)
    client = LinkClient(stream, retries=3)
    try:
        got = client.request(Command.MOTION, b"\x11", reply_length=1)
    except LinkError:
        return
    assert got == payload
    good = [i for i, how in enumerate(hows[:stream.writes]) if how[0] in ("none", "garbage")]
    assert good, (hows, noise)  # a reply was taken only where one came through intact
    assert stream.writes <= client.retries + 1


@settings(max_examples=100, deadline=2000)
@given(stream_bytes=st.binary(max_size=300))
def test_random_bytes_are_never_a_reply(stream_bytes):
    client = LinkClient(_ScriptedStream([stream_bytes] * 4), retries=3)
    with pytest.raises(LinkError):
        client.request(Command.MOTION, b"\x11", reply_length=1)


class _EndlessStream:
    """A line that never falls silent: ``pattern`` over and over (noise, or frames of other tags)."""

    port = "endless"

    def __init__(self, pattern: bytes):
        self.pattern, self.at, self.read_bytes = pattern, 0, 0

    def write(self, data):
        return len(data)

    def read(self, n):
        out = bytes(self.pattern[(self.at + i) % len(self.pattern)] for i in range(n))
        self.at += n
        self.read_bytes += n
        return out

    def reset_input_buffer(self):
        pass


@settings(max_examples=60, deadline=5000)
@given(noise=st.binary(min_size=1, max_size=64), late=st.booleans())
def test_a_line_that_never_falls_silent_does_not_hang_the_host(noise, late):
    """Endless noise, or endless good frames of another tag (a board stuck repeating a reply):
    every try gives up after a bounded number of bytes, and the request ends in LinkError."""
    pattern = encode_frame(Command.MOTION, b"\x02", tag=200) + noise if late else noise
    stream = _EndlessStream(pattern)
    with pytest.raises(LinkError):
        LinkClient(stream, retries=3).request(Command.MOTION, b"\x11", reply_length=1)
    assert stream.read_bytes < 4 * 8 * (262 + len(pattern)) + 4 * 600


# -- whole lifetimes -----------------------------------------------------------------------------


def test_a_lifetime_over_a_noisy_line_is_the_clean_one(ehw, tmp_path):
    """--targets 4 over the emulated board with bit flips, dropped bytes, silent replies and 3
    board resets: the reference's summary and motions; the summary counts the faults."""
    assert ehw("sim", *LIFETIME, "--out", "ref")[0] == 0
    status, out, err = ehw("sim", "--backend", "emulated", *LIFETIME, "--out", "noisy", "--line-faults", FAULTS)
    assert status == 0, err
    _same_lifetime(tmp_path / "ref", tmp_path / "noisy")
    faults = json.loads((tmp_path / "noisy/summary.json").read_text())["line_faults"]["controller"]
    assert faults["injected"]["reset"] == faults["resets_detected"] == faults["restores"] + faults["restore_restarts"] == 3
    assert min(faults["injected"][k] for k in ("flip", "drop", "silence")) > 0
    assert faults["resends"] > 0 and faults["bytes_resent"] > 0
    assert "line faults (controller): injected" in out


def test_every_motion_over_a_noisy_line_is_the_clean_ones(monkeypatch):
    from cosim.online.config import OnlineConfig
    from cosim.online.run import make_run

    config = OnlineConfig(seed=1, n_targets=4, population=20)
    clean = make_run(config, "reference").run()
    monkeypatch.setenv("EHW_LINE_FAULTS", "flip=2e-4,drop=1e-4,silence=2e-3,reset=4,seed=5")
    noisy = make_run(config, "emulated").run()
    assert noisy.controller.client.stats.resets == 4
    assert bytes(noisy.motions) == bytes(clean.motions) and len(clean.motions) == clean.interactions


def test_a_dead_line_stops_with_one_error_and_resumes(ehw, tmp_path):
    short = ["--targets", "2", "--population", "20", "--quiet", "--no-plots"]
    assert ehw("sim", *short, "--out", "ref")[0] == 0
    status, _, err = ehw("sim", "--backend", "emulated", *short, "--out", "dead", "--line-faults", "dead=3000")
    one_error(status, err, "line went dead", "READ_COUNTERS")
    assert (tmp_path / "dead/checkpoint.json").is_file() and not (tmp_path / "dead/summary.json").exists()
    status, _, err = ehw("sim", "--backend", "emulated", "--resume", "--out", "dead", "--line-faults", "",
                         "--quiet", "--no-plots")
    assert status == 0, err
    _same_lifetime(tmp_path / "ref", tmp_path / "dead")


@pytest.mark.parametrize("args, words", [
    (["--backend", "reference", "--line-faults", "flip=0.1"], ["--line-faults", "reference"]),
    (["--backend", "serial", "--port", "loop://", "--line-faults", "reset=1"], ["reset=1", "real board"]),
    (["--backend", "emulated", "--line-faults", "flip=7"], ["flip"])])
def test_line_fault_options_are_checked_first(ehw, tmp_path, args, words):
    one_error(*ehw("sim", *args, "--targets", "1", "--out", "x")[::2], *words)
    assert not (tmp_path / "x").exists()


def test_the_option_wins_over_the_environment(ehw, monkeypatch):
    monkeypatch.setenv("EHW_LINE_FAULTS", "dead=40")
    small = ["--backend", "emulated", "--arena", "empty", "--targets", "1", "--population", "4", "--quiet",
             "--no-plots"]
    one_error(*ehw("sim", *small, "--out", "env")[::2], "line went dead")
    status, _, err = ehw("sim", *small, "--out", "clean", "--line-faults", "")
    assert status == 0, err

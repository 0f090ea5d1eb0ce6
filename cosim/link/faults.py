"""Seeded faults on any serial line of the host link: ``--line-faults flip=P,drop=P,silence=P,reset=N,seed=S``.

:class:`FaultyLine` wraps a byte stream (pyserial's ``write`` / ``read`` / ``reset_input_buffer``:
a real port, the simulated lines of ``cosim.link.simulated``, the emulated board of
``cosim.link.emulated``) and damages what crosses it, as a long or noisy cable would:

- ``flip=P``: each byte, either way, has one random bit inverted with probability P;
- ``drop=P``: each byte from the host is lost with probability P;
- ``silence=P``: each request frame's reply is lost whole with probability P (the board executed
  the request: the host's resend must be harmless);
- ``reset=N``: N board resets (a power glitch or a USB re-plug: the board loses its world-model
  RAM, rate codes, controller and population, and the frame then in flight), at request frames
  drawn uniformly from ``reset_from``..``reset_within`` (default 8..4000); needs a line that can
  reset its board (``board_reset()``: the simulated and emulated lines; not a real port);
- ``dead=K``: from request frame K on the line carries nothing at all (the host must give up
  with one ``error:`` line, the run keeping its last checkpoint);
- ``seed=S``: the faults' own generator (``numpy.random.default_rng(S)``, default 1): the same
  spec on the same traffic gives the same faults.

The host (``cosim.link.host.LinkClient``) must detect each fault (CRC, tags, time-outs, the
board's frame counter) and recover; ``injected`` counts what this wrapper did, for the run's
``link.json``. Every frame of the host is one ``write`` call (``LinkClient`` writes a frame whole),
so the wrapper counts frames by calls.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from base.errors import UserError

FAULTS_ENV = "EHW_LINE_FAULTS"  # how --line-faults reaches the boards' factories (base.environ)
RATES = ("flip", "drop", "silence")
COUNTS = ("reset", "dead", "seed", "reset_from", "reset_within")


@dataclass(frozen=True)
class LineFaults:
    """The faults of one line (see the module docstring); all zero: a clean line."""

    flip: float = 0.0
    drop: float = 0.0
    silence: float = 0.0
    reset: int = 0
    dead: int = 0  # 0: never
    seed: int = 1
    reset_from: int = 8
    reset_within: int = 4000

    def __post_init__(self):
        for name in RATES:
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and 0 <= value < 1):
                raise ValueError(f"{name}={value!r}: a probability in [0, 1)")
        for name in COUNTS:
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 0:
                raise ValueError(f"{name}={value!r}: a count >= 0")
        if self.reset and self.reset_within - self.reset_from < self.reset:
            raise ValueError(f"reset={self.reset}: more resets than frames in "
                             f"{self.reset_from}..{self.reset_within}")

    @property
    def any(self) -> bool:
        return bool(self.flip or self.drop or self.silence or self.reset or self.dead)

    def to_text(self) -> str:
        return ",".join(f"{k}={v!r}" for k, v in asdict(self).items() if v != getattr(LineFaults, k))


def parse_faults(text: str | None, where: str = "--line-faults") -> LineFaults | None:
    """``flip=P,drop=P,silence=P,reset=N,dead=K,seed=S`` (any subset), or None for none/empty;
    a bad spec is a UserError naming ``where`` and the bad item."""
    if text is None or not str(text).strip():
        return None
    fields = {}
    for item in str(text).split(","):
        key, sep, value = item.strip().partition("=")
        if not sep or key not in (*RATES, *COUNTS):
            raise UserError(f"{where} {text!r}: {item.strip()!r} is not KEY=VALUE with KEY one of "
                            f"{', '.join((*RATES, *COUNTS))}")
        if key in fields:
            raise UserError(f"{where} {text!r}: {key} given twice")
        try:
            fields[key] = float(value) if key in RATES else int(value, 10)
        except ValueError:
            raise UserError(f"{where} {text!r}: {key}={value!r} is not a "
                            f"{'probability' if key in RATES else 'count'}") from None
    try:
        faults = LineFaults(**fields)
    except ValueError as exc:
        raise UserError(f"{where} {text!r}: {exc}") from None
    return faults if faults.any else None


class FaultyLine:
    """A byte stream with :class:`LineFaults` on it (see the module docstring)."""

    def __init__(self, stream, faults: LineFaults):
        if faults.reset and not callable(getattr(stream, "board_reset", None)):
            raise UserError(f"--line-faults reset={faults.reset}: the line {getattr(stream, 'port', stream)!r} "
                            "cannot reset its board from the host (a real board: power-cycle or "
                            "re-plug it; the host recovers the same way)")
        self.stream, self.faults = stream, faults
        self.port = getattr(stream, "port", "stream")
        self.rng = np.random.default_rng(faults.seed)
        self.frames = 0  # request frames written (one write a frame)
        self.injected = {"flip": 0, "drop": 0, "silence": 0, "reset": 0, "dead": 0}
        span = range(faults.reset_from, faults.reset_within)
        self._resets = set(int(f) for f in self.rng.choice(len(span), faults.reset, replace=False) + span.start) \
            if faults.reset else set()
        self._muted = False  # this frame's reply is being swallowed
        self._swallowed = False

    @property
    def timeout(self):
        return getattr(self.stream, "timeout", None)

    def _dead(self) -> bool:
        return bool(self.faults.dead) and self.frames >= self.faults.dead

    def _flip(self, data: bytes) -> bytes:
        if not self.faults.flip or not data:
            return data
        hit = np.flatnonzero(self.rng.random(len(data)) < self.faults.flip)
        if not len(hit):
            return data
        out = bytearray(data)
        for i in hit:
            out[i] ^= 1 << int(self.rng.integers(8))
        self.injected["flip"] += len(hit)
        return bytes(out)

    def write(self, data: bytes) -> int:
        data = bytes(data)
        self.frames += 1
        if self._dead():
            self.injected["dead"] = 1
            return len(data)
        if self.frames in self._resets:  # the board resets while this frame arrives: it is lost
            self.injected["reset"] += 1
            self.stream.board_reset()
            self._muted = False
            return len(data)
        self._muted = bool(self.faults.silence) and self.rng.random() < self.faults.silence
        self._swallowed = False
        if self.faults.drop:
            keep = self.rng.random(len(data)) >= self.faults.drop
            self.injected["drop"] += int((~keep).sum())
            data = bytes(b for b, k in zip(data, keep) if k)
        data = self._flip(data)
        if data:
            self.stream.write(data)
        return len(data)

    def read(self, n: int) -> bytes:
        got = bytes(self.stream.read(n))
        if self._muted and got and not self._swallowed:  # counted once a reply it swallows
            self.injected["silence"] += 1
            self._swallowed = True
        if self._muted or self._dead():
            return b""
        return self._flip(got)

    def reset_input_buffer(self) -> None:
        self._muted = False
        self.stream.reset_input_buffer()


def faulty(stream, text: str | None = None):
    """``stream`` behind the faults of ``text`` (default: ``EHW_LINE_FAULTS``), or ``stream`` itself."""
    if text is None:
        from base import environ

        text = environ.read(FAULTS_ENV)
    faults = parse_faults(text)
    return stream if faults is None else FaultyLine(stream, faults)


def injected_faults(client) -> dict | None:
    """What the :class:`FaultyLine` under ``client`` injected (None on a clean line)."""
    stream = getattr(client, "stream", None)
    return dict(stream.injected) if isinstance(stream, FaultyLine) else None

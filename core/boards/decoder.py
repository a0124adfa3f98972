"""A board's bytes into the desk's samples: one streaming stage for a port, a file or a test.

``BoardDecoder(profile, settings).push(chunks)`` takes what the port gave ((host time, bytes)
pairs, any split) and returns the samples now complete: their times on the board's clock,
each channel scaled and aligned to the sample's time, in the profile's channel order. The
first hello (:mod:`~hapticdesk.boards.hello`) is checked against the desk — the same
channels in the same order, the same rate, sampling offsets known — and a board that does
not match is refused with both lists named. A later hello the host did not ask for (with
``?``) means the board restarted; a hello that says something else means another board,
which stops the source. Counts and notices are in :attr:`BoardDecoder.stats`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hapticdesk.boards.alignment import ChannelAligner
from hapticdesk.boards.clock import BoardClock, ClockEvent
from hapticdesk.boards.hello import BoardHello, parse_hello
from hapticdesk.boards.lines import (
    BEFORE_HELLO,
    COMMENT,
    GARBLED,
    HELLO,
    OVERLONG,
    REASONS,
    LineBatch,
    LineSplitter,
    line_kinds,
    parse_lines,
)
from hapticdesk.boards.settings import SerialSettings, board_channels
from hapticdesk.boards.stats import SerialStats, log
from hapticdesk.errors import ConfigError
from hapticdesk.files.profile import DeskProfile

#: the board's rate may differ from the profile's by this share at most
RATE_TOLERANCE = 0.005


@dataclass
class DecodedBlock:
    """Samples decoded by one push: ``t`` (k,), ``channels`` (k, C) in the profile's channel
    order, ``accel`` (k, A) the accelerometers' readings where the desk has some."""

    t: np.ndarray
    channels: np.ndarray
    accel: np.ndarray | None = None


class BoardDecoder:
    """Bytes from one board into samples of ``profile`` (module docstring). ``where`` names
    the port in messages."""

    def __init__(self, profile: DeskProfile, settings: SerialSettings, where: str = "") -> None:
        self.profile = profile
        self.settings = settings
        self.where = where or settings.port
        self.expected = board_channels(profile)
        self.n_sensor_channels = profile.channel_count
        self.stats = SerialStats()
        self.hello: BoardHello | None = None
        self.asked = True  # the host asked for a hello (at opening): the next is no restart
        self.last_line = b""  # the last complete line read (for a message)
        self._splitter = LineSplitter()
        self._lines_before = 0  # lines read before the port was last opened again
        self._clock: BoardClock | None = None
        self._aligner: ChannelAligner | None = None
        self._offsets: np.ndarray | None = None  # fixed offsets (C,), µs; None: per line
        self._held: tuple[np.ndarray, ...] | None = None  # a sample waiting for its successor

    # --- public -------------------------------------------------------------------------

    def push(self, chunks: list[tuple[float, bytes]], *, final: bool = False) -> DecodedBlock:
        """Decode ``chunks`` ((host time, bytes) in arrival order); ``final``: nothing more
        comes, so a sample held to judge its stamp is judged now."""
        self.stats.bytes += sum(len(c) for _, c in chunks)
        batch = self._splitter.feed(chunks)
        for number, head in batch.overlong:
            self._garbled(OVERLONG, number, head)
        self.stats.lines = self._lines_before + self._splitter.lines
        if len(batch):
            self.last_line = batch.text(len(batch) - 1)
        hellos = np.flatnonzero(batch.first_bytes() == ord("@"))  # (checked by _hello)
        parts: list[DecodedBlock] = []
        start = 0
        for h in [*hellos.tolist(), len(batch)]:
            if h > start:
                parts.append(
                    self._lines(batch.take(slice(start, h)), final=final and h == len(batch))
                )
            if h < len(batch):
                self._hello(batch, h)
            start = h + 1
        if final and self._held is not None:
            parts.append(self._samples(*self._take_held(), final=True))
        return self._join(parts)

    def reconnected(self) -> None:
        """The port was opened again: the next samples begin a new epoch (a gap), and the
        hello the host asks for is no restart."""
        self.stats.reconnects += 1
        self.asked = True
        self._lines_before += self._splitter.lines
        self._splitter = LineSplitter()  # half a line from before is garbage
        if self._clock is not None:
            self._clock.restart("the port was opened again", board_restarted=False)

    @property
    def last_t(self) -> float | None:
        return self._clock.last_t if self._clock is not None else None

    # --- hello --------------------------------------------------------------------------

    def _hello(self, batch: LineBatch, i: int) -> None:
        kind, _, _ = line_kinds(batch.take(slice(i, i + 1)), False)
        number = int(batch.numbers[i])
        if kind[0] != HELLO:  # a hello whose checksum does not match, or not text
            self._garbled(int(kind[0]), number, batch.text(i))
            return
        text = batch.text(i).decode("ascii").rsplit("*", 1)[0].strip()
        where = f"{self.where} line {number}"
        self.stats.hellos += 1
        try:
            hello = parse_hello(text, where)
        except ConfigError as err:
            if self.hello is None:
                raise
            self._notice("garbled", f"{where}: a hello that cannot be read ({err.message})")
            return
        if self.hello is None:
            self._first_hello(hello, where)
        elif hello != self.hello:
            raise ConfigError(
                where,
                f"the board changed: it said `{self.hello.text()}` before and now "
                f"`{hello.text()}`; restart the run for another board",
            )
        elif not self.asked:
            assert self._clock is not None
            self._clock.restart("the board said hello again: it restarted")
        self.asked = False

    def _first_hello(self, hello: BoardHello, where: str) -> None:
        expected, rate = self.expected, self.profile.sample_rate_hz
        if list(hello.channels) != expected:
            same = sorted(hello.channels) == sorted(expected)
            raise ConfigError(
                where,
                ("the board sends the desk's channels in another order" if same else
                 f"the board is not for desk `{self.profile.name}`")
                + f": it sends {','.join(hello.channels)}; the desk's channels are "
                f"{','.join(expected)} (profile {self.profile.path or self.profile.name}); a "
                "wrong board, or cells wired in another order: print them in the desk's order",
            )  # fmt: skip
        if abs(hello.rate_hz - rate) > RATE_TOLERANCE * rate:
            raise ConfigError(
                where,
                f"the board samples at {hello.rate_hz:g} Hz but desk `{self.profile.name}` "
                f"says `sample_rate_hz: {rate:g}`: make them agree",
            )
        offsets = hello.offsets_us if hello.offsets_us is not None else self.settings.offsets_us
        if offsets is None and not hello.offsets_per_line and not self.settings.simultaneous:
            raise ConfigError(
                where,
                "the board does not say when each channel is sampled (`offsets_us=` or "
                "`offsets=line` in its hello) and the profile's `serial:` neither gives "
                "`offsets_us` nor says `simultaneous: true`: channels read apart make a false "
                "moment while the force changes (docs/serial.md); say which",
            )
        self.hello = hello
        self._clock = BoardClock(hello, self.profile.estimation.max_gap_s)
        if hello.offsets_per_line or (offsets is not None and any(offsets)):
            self._aligner = ChannelAligner(len(expected))
        self._offsets = (
            None if hello.offsets_per_line else np.array(offsets or [0.0] * len(expected))
        )
        board = f" ({hello.board})" if hello.board else ""
        log.info(
            "%s: board%s at %g Hz, %d channels, stamp %s",
            self.where, board, hello.rate_hz, len(expected), hello.stamp,
        )  # fmt: skip

    # --- samples ------------------------------------------------------------------------

    def _lines(self, batch: LineBatch, final: bool) -> DecodedBlock:
        parsed = parse_lines(batch, self.hello)
        kind = parsed.kind
        self.stats.comments += int(np.count_nonzero(kind == COMMENT))
        self.stats.before_hello += int(np.count_nonzero(kind == BEFORE_HELLO))
        for i in np.flatnonzero(kind >= GARBLED):  # rare: each is named
            self._garbled(int(kind[i]), int(batch.numbers[i]), batch.text(int(i)))
        if self.hello is None or not len(parsed.rows):
            return self._join([])
        rows = parsed.rows
        offsets = parsed.offsets if parsed.offsets is not None else np.zeros((len(rows), 0))
        arrays: tuple[np.ndarray, ...] = (
            parsed.stamps, batch.host_t[rows], batch.numbers[rows], parsed.values, offsets
        )  # fmt: skip
        if self._held is not None:
            held = self._take_held()
            arrays = tuple(np.concatenate([a, b]) for a, b in zip(held, arrays, strict=True))
        return self._samples(*arrays, final=final)

    def _take_held(self) -> tuple[np.ndarray, ...]:
        held, self._held = self._held, None
        assert held is not None
        return held

    def _samples(
        self,
        stamps: np.ndarray,
        host_t: np.ndarray,
        numbers: np.ndarray,
        values: np.ndarray,
        offsets: np.ndarray,
        *,
        final: bool,
    ) -> DecodedBlock:
        assert self._clock is not None
        placed = self._clock.place(stamps, host_t, numbers, final=final)
        m = len(stamps) - placed.held
        self.stats.sample_lines += m
        if placed.held:
            self._held = tuple(a[m:] for a in (stamps, host_t, numbers, values, offsets))
        for i in np.flatnonzero(placed.dropped):
            self._garbled(int(placed.dropped[i]), int(numbers[i]), f"stamp {stamps[i]}".encode())
        kept = np.flatnonzero(placed.dropped == 0)
        for event in placed.events:
            self._event(event)
        self.stats.lost += placed.lost
        raw = values[kept]
        self.stats.missing_values += int(np.isnan(raw).sum())
        scaled = (raw - self.settings.zero) * self.settings.scale
        if self._aligner is not None:
            offs = (
                offsets[kept]
                if self._offsets is None
                else np.broadcast_to(self._offsets, scaled.shape)
            )
            before = self._aligner.unaligned
            scaled = self._aligner.align(placed.times, scaled, offs, placed.fresh)
            self.stats.unaligned += self._aligner.unaligned - before
        self.stats.samples += len(kept)
        return self._block(placed.times, scaled)

    def _block(self, t: np.ndarray, channels: np.ndarray) -> DecodedBlock:
        c = self.n_sensor_channels
        accel = channels[:, c:] if channels.shape[1] > c else None
        return DecodedBlock(t, channels[:, :c], accel)

    def _join(self, parts: list[DecodedBlock]) -> DecodedBlock:
        parts = [p for p in parts if len(p.t)]
        if not parts:
            n = len(self.expected)
            return self._block(np.zeros(0), np.zeros((0, n)))
        if len(parts) == 1:
            return parts[0]
        t = np.concatenate([p.t for p in parts])
        channels = np.concatenate([p.channels for p in parts])
        accels = [p.accel for p in parts if p.accel is not None]
        return DecodedBlock(
            t, channels, np.concatenate(accels) if len(accels) == len(parts) else None
        )

    # --- telling ------------------------------------------------------------------------

    def _garbled(self, code: int, number: int, text: bytes) -> None:
        self.stats.garbled[code] = self.stats.garbled.get(code, 0) + 1
        self._notice(
            "garbled", f"{self.where} line {number}: garbled, {REASONS[code]}: {text[:60]!r}"
        )

    def _event(self, event: ClockEvent) -> None:
        if event.kind == "lost":
            self.stats.loss_runs += 1
            text = f"{event.count} samples lost before t={event.t:.4f} s (the stamp jumped)"
        elif event.kind == "gap":
            text = (
                f"no samples for {event.seconds:.3f} s before t={event.t:.4f} s; the "
                "estimator restarts its filters there"
            )
        else:  # a new epoch: "reset" (the board restarted) or "resume" (the port reopened)
            text = (
                f"{event.detail}; carrying on at t={event.t:.4f} s after a gap of "
                f"{event.seconds:.3f} s"
            )
        self.stats.gaps += event.kind != "lost"
        self.stats.resets += event.kind == "reset"
        self._notice(event.kind, f"{self.where} line {event.line}: {text}")

    def _notice(self, kind: str, message: str) -> None:
        self.stats.notice(kind, self.last_t, message)

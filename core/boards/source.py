"""The live ``serial:`` source: a board's lines read through pyserial into wrench blocks.

    hapticdesk run --layout L --source serial:/dev/ttyUSB0?baud=921600

A reader thread of its own moves every byte the port gives into a queue at once, so the
operating system's small buffer (4 KiB on Linux, 0.1 s of a 1 kHz board) never overflows
while the estimator works; the queue holds at most :data:`MAX_QUEUED_BYTES` (then the reader
waits and the port's flow control, or the board, holds the rest). Opening sends ``?`` and
waits up to ``hello_timeout_s`` for the board's hello (asked again every second), so a
wrong board or channel order is refused before the run starts.

A port that fails (unplugged, a USB reset) is opened again every
:data:`RECONNECT_INTERVAL_S` until ``reconnect_timeout_s`` has passed, then the source stops
with a clear error; the samples after it begin a new epoch (a gap, never bridged). pyserial
is imported only here: a missing one is named with its install command.
"""

from __future__ import annotations

import collections
import threading
import time
from typing import Any

from hapticdesk.boards.decoder import BoardDecoder, DecodedBlock
from hapticdesk.boards.settings import serial_settings
from hapticdesk.errors import ConfigError
from hapticdesk.files.profile import DeskProfile
from hapticdesk.runtime.source import Source, WrenchBlock

BLOCK_WAIT_S = 0.01  # a block gathers what came within this long
READ_TIMEOUT_S = 0.05  # the reader thread's longest wait in one read (bounds close())
RECONNECT_INTERVAL_S = 0.2
ASK_AGAIN_S = 1.0  # while waiting for the hello, `?` is sent this often
MAX_QUEUED_BYTES = 64 * 1024 * 1024  # read, not yet decoded: ~20 min of a 1 kHz board
ASK_HELLO = b"?\n"
INSTALL = "pip install 'hapticdesk[serial]'"


class SerialSourceError(ConfigError):
    """The port could not be opened, said nothing readable, or was lost for good."""


def import_pyserial() -> Any:
    """The ``serial`` module of pyserial, or a ConfigError saying how to install it."""
    try:
        import serial
    except ImportError:
        raise SerialSourceError(
            "--source", f"the serial source needs pyserial: {INSTALL}"
        ) from None
    if not hasattr(serial, "serial_for_url"):  # the unrelated PyPI package `serial`
        raise SerialSourceError(
            "--source",
            "the `serial` module installed is not pyserial (another package has the same "
            f"name): pip uninstall serial, then {INSTALL}",
        )
    return serial


class SerialSource(Source):
    """Samples of a desk read from a board on a serial port (module docstring)."""

    def __init__(self, spec: str, profile: DeskProfile) -> None:
        self.serial = import_pyserial()  # (before the base: nothing to close if it fails)
        self.settings = serial_settings(profile, spec)
        super().__init__(
            profile.sensor_names, profile.sample_rate_hz, channel_count=profile.channel_count
        )
        self.profile = profile
        self.port_name = self.settings.port
        self.decoder = BoardDecoder(profile, self.settings, where=self.port_name)
        self._queue: collections.deque[tuple[float, bytes]] = collections.deque()
        self._queued = 0
        self._moved = threading.Condition()
        self._write_lock = threading.Lock()
        self._fault: str | None = None
        self._waiting: list[DecodedBlock] = []
        self._last_bytes_at = time.monotonic()
        self._silent_told = False
        self.silences = 0
        self._reader: threading.Thread | None = None
        self._port: Any = None
        try:
            self._port = self._open()
            self._start_reader()
            self._await_hello()
        except BaseException:
            self.close()
            raise

    def summary(self) -> list[str]:
        lines = self.decoder.stats.summary()
        if self.silences:
            lines.append(
                f"{self.silences} silences of {self.settings.silent_timeout_s:g} s or more"
            )
        if not self.settings.scale_given:  # (raw counts as newtons: the desk never tares)
            lines.append(
                "no `scale` given (the profile's `serial: scale` or ?scale=): the board's values "
                "were taken as newtons; a board printing its converters' counts needs one"
            )
        return [f"serial {self.port_name}: {line}" for line in lines]

    # --- the port -----------------------------------------------------------------------

    def _open(self) -> Any:
        try:
            port = self.serial.serial_for_url(
                self.port_name, baudrate=self.settings.baud, timeout=READ_TIMEOUT_S
            )
        except (self.serial.SerialException, OSError, ValueError) as err:
            raise SerialSourceError(
                "--source", f"cannot open serial port {self.port_name}: {err}"
            ) from None
        self._ask(port)
        return port

    def _ask(self, port: Any) -> None:
        """Ask the board for its hello (a board that is already running says it again)."""
        with self._write_lock:
            try:
                port.write(ASK_HELLO)
            except (self.serial.SerialException, OSError) as err:
                self._fault = self._fault or f"cannot write to the port: {err}"

    def _start_reader(self) -> None:
        self._fault = None
        self._reader = threading.Thread(
            target=self._read_port, args=(self._port,), name="serial-reader", daemon=True
        )
        self._reader.start()

    def _read_port(self, port: Any) -> None:
        """The reader thread: every byte into the queue, at once (module docstring)."""
        while not self.closing:
            try:
                data = port.read(max(1, min(port.in_waiting, 65536)))
            except Exception as err:  # pyserial: SerialException, OSError, TypeError on close
                if not self.closing:
                    with self._moved:
                        self._fault = f"{type(err).__name__}: {err}"
                        self._moved.notify_all()
                return
            if not data:
                continue
            with self._moved:
                while self._queued > MAX_QUEUED_BYTES and not self.closing:
                    self._moved.wait(0.1)
                self._queue.append((time.monotonic(), data))
                self._queued += len(data)
                self._moved.notify_all()

    def _take(self, wait_s: float) -> list[tuple[float, bytes]]:
        """What the reader queued within ``wait_s`` (a block's worth, not a read's)."""
        deadline = time.monotonic() + wait_s
        with self._moved:
            while self._fault is None and not self.closing:
                left = deadline - time.monotonic()
                if left <= 0:
                    break
                self._moved.wait(left)
            chunks = list(self._queue)
            self._queue.clear()
            self._queued = 0
            self._moved.notify_all()
        return chunks

    def _await_hello(self) -> None:
        """Read until the board's hello is in (the samples after it wait for blocks())."""
        started = time.monotonic()
        asked = started
        while self.decoder.hello is None:
            now = time.monotonic()
            if now - started > self.settings.hello_timeout_s:
                stats = self.decoder.stats
                last = self.decoder.last_line.decode("ascii", "backslashreplace")
                raise SerialSourceError(
                    f"--source serial:{self.port_name}",
                    f"no hello from the board within {self.settings.hello_timeout_s:g} s "
                    f"({stats.bytes} bytes, {stats.lines} lines read"
                    + (f"; the last: {last[:60]!r}" if last else "")
                    + f"): is it a hapticdesk board (docs/serial.md), at {self.settings.baud} "
                    "baud? (`hello_timeout_s` waits longer)",
                )
            if now - asked > ASK_AGAIN_S:
                self._ask(self._port)
                asked = now
            chunks = self._take(0.1)
            if self._fault is not None:
                raise SerialSourceError(
                    f"--source serial:{self.port_name}", f"the port failed: {self._fault}"
                )
            if chunks:
                self._waiting.append(self.decoder.push(chunks))

    def _reconnect(self) -> None:
        """The port failed: open it again until it works or ``reconnect_timeout_s`` passes."""
        why = self._fault
        self.decoder.stats.notice(
            "port", self.decoder.last_t, f"serial port {self.port_name} failed ({why}); reopening"
        )
        self._shut_port()
        deadline = time.monotonic() + self.settings.reconnect_timeout_s
        while not self.closing:
            try:
                port = self._open()
            except SerialSourceError as err:
                if time.monotonic() >= deadline:
                    raise SerialSourceError(
                        f"--source serial:{self.port_name}",
                        f"the serial port was lost ({why}) and did not come back within "
                        f"{self.settings.reconnect_timeout_s:g} s: {err.message}",
                    ) from None
                self._closing.wait(RECONNECT_INTERVAL_S)
                continue
            self._port = port
            self.decoder.reconnected()
            self._start_reader()
            self.decoder.stats.notice(
                "port", self.decoder.last_t, f"serial port {self.port_name} is back"
            )
            return

    def _shut_port(self) -> None:
        port, self._port = self._port, None
        reader = self._reader
        if reader is not None and reader is not threading.current_thread():
            reader.join(timeout=2 * READ_TIMEOUT_S + 1.0)
        if port is not None:
            try:
                port.close()
            except Exception:  # a broken driver must not hide why we are closing
                pass

    # --- blocks -------------------------------------------------------------------------

    def read_block(self) -> WrenchBlock | None:
        if self._waiting:
            return self._wrench(self._waiting.pop(0))
        chunks = self._take(BLOCK_WAIT_S)
        now = time.monotonic()
        if chunks:
            self._last_bytes_at, self._silent_told = now, False
        elif not self._silent_told and now - self._last_bytes_at > self.settings.silent_timeout_s:
            self._silent_told = True
            self.silences += 1
            self.decoder.stats.notice(
                "silent",
                self.decoder.last_t,
                f"no data from serial port {self.port_name} for "
                f"{self.settings.silent_timeout_s:g} s",
            )
        if self._fault is not None and not self.closing:
            block = self.decoder.push(chunks, final=True)  # what came before the fault
            self._reconnect()
            return self._wrench(block)
        return self._wrench(self.decoder.push(chunks))

    def _wrench(self, block: DecodedBlock) -> WrenchBlock:
        readings = block.channels
        if self.profile.six_axis_only:  # the six-axis layout other consumers know
            readings = readings.reshape(len(readings), len(self.sensor_names), 6)
        return WrenchBlock(block.t, readings, accel=block.accel)

    def release(self) -> None:
        with self._moved:
            self._moved.notify_all()
        self._shut_port()


def open_serial_source(spec: str, profile: DeskProfile) -> SerialSource:
    """Open the board of ``profile`` at ``spec`` (``PORT[?key=value&…]``; see
    :mod:`hapticdesk.boards.settings`); waits for its hello."""
    return SerialSource(spec, profile)

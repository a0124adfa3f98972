"""The run loop: source → estimator → gesture engine → dispatcher, until the source ends.

One *sensing* thread reads blocks, estimates contacts, recognises gestures, writes the events
file (:mod:`.events_file`) and hands events to the dispatcher (which never blocks it); it
applies the commands queued for the run between two blocks, a reload's new layout built and
swapped in by :mod:`.layout_reload`. The calling thread watches:
it draws the status line and turns SIGINT/SIGTERM into a clean stop. At the end the gesture
engine is flushed (a pending tap is decided), queued commands get a bounded time to go out,
and what did not is reported.

What runs is built by :func:`~hapticdesk.runtime.assembly.build_scene`; this module names no
plugin.
"""

from __future__ import annotations

import contextlib
import logging
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator
from concurrent.futures import Future
from pathlib import Path
from typing import IO, Any

from hapticdesk.errors import ConfigError
from hapticdesk.gestures.event import GestureEvent
from hapticdesk.hookspecs import RunView
from hapticdesk.runtime.assembly import Assembly
from hapticdesk.runtime.control import MAX_PAUSE_S, ControlCommand, ControlError, pause_seconds
from hapticdesk.runtime.events_file import EventsFile
from hapticdesk.runtime.layout_reload import LayoutReloads
from hapticdesk.runtime.live_status import LiveStatus
from hapticdesk.runtime.operator_secrets import OperatorSecrets
from hapticdesk.runtime.run_report import RunReport
from hapticdesk.runtime.signal_handoff import signals_handed_off

log = logging.getLogger(__name__)

STATUS_INTERVAL_S = 0.1


class Runtime:
    """Runs an :class:`Assembly` until its source ends or :meth:`stop` is called."""

    def __init__(
        self,
        scene: Assembly,
        *,
        events_path: str | Path | None = None,
        status: IO[str] | None = None,
        drain_timeout_s: float = 5.0,
    ) -> None:
        self.scene = scene
        #: ``--events``: one JSON line per gesture event
        self.events = EventsFile(events_path)
        self.status_stream = status
        self.drain_timeout_s = drain_timeout_s
        self.live = LiveStatus()
        self.report = RunReport()
        self._stop = threading.Event()
        self._force = False
        #: callables given every block's ``(t, wrench)`` on the sensing thread, after the
        #: estimator (a set-up check recording raw samples); each must be O(1): keep a
        #: reference, never copy or wait. Replaced whole (a tuple), never changed in place.
        self.block_taps: tuple[Any, ...] = ()
        #: gestures are recognised but not sent while paused (``pause`` / ``resume``), until
        #: ``_paused_until`` (monotonic time) at the latest
        self.paused = False
        self._paused_until: float | None = None
        self._t_last: float | None = None  # the last sample time sensed (to flush an engine)
        self._tared_once = False  # the zero was taken at some block (else the run says so)
        self.layout_path = scene.layout_path or scene.layout.path
        #: the layouts ``layout NAME`` switches among (from the layout the run started with)
        self.named_layouts: dict[str, Path] = {
            "default": Path(self.layout_path),
            **getattr(scene.layout, "named_layouts", {}),
        }
        #: what the layouts the run started with read from the environment and files, run
        #: and connect to: a reload may not add or change any of it
        self.operator_secrets = OperatorSecrets.from_start(
            scene.layout.raw, Path(self.layout_path), scene.registry, self.named_layouts
        )
        #: a reload's layout, built and waiting for the touch in progress to end
        self.reloads = LayoutReloads(scene, self.operator_secrets, self._emit, drain_timeout_s)

    # --- control: what the desk can be told while it runs ------------------------------------

    def request(self, name: str | ControlCommand, argument: str | None = None) -> Future[str]:
        """Queue a command (``tare``, ``pause``, ``resume``, ``reload``, ``layout NAME``; see
        :mod:`hapticdesk.runtime.control`) from any thread; never blocks. The sensing thread
        applies it before the next block; the future then holds a line saying what was done,
        or the error (a layout that does not load leaves the running one in place)."""
        return self.scene.control.request(name, argument)

    def reload(self, timeout_s: float = 10.0) -> str:
        """Read the layout file again and use it, keeping the zero and the connections
        (for the browser UI after it saved the layout). Waits up to ``timeout_s`` for the
        sensing thread; raises ConfigError when the layout does not load (the old one stays)
        and TimeoutError when the run is not sensing."""
        return self.request("reload").result(timeout_s)

    def switch_layout(self, name: str, timeout_s: float = 10.0) -> str:
        """Switch to the named layout (``layouts:`` of the first layout, or ``default``)."""
        return self.request("layout", name).result(timeout_s)

    def apply_control(self) -> None:
        """Apply every queued command (on the sensing thread, between blocks)."""
        for cmd, future in self.scene.control.take():
            try:
                line = self._apply(cmd)
            except (ControlError, ConfigError) as err:
                log.warning("control: `%s` refused: %s", cmd, err)
                future.set_exception(err)
            except Exception as err:  # a bug: the run goes on with what it had
                log.exception("control: `%s` failed", cmd)
                future.set_exception(err)
            else:
                log.warning("control: %s", line)
                future.set_result(line)

    def _apply(self, cmd: ControlCommand) -> str:
        scene = self.scene
        if cmd.name == "tare":
            scene.estimator.retare()
            self.live.tared = False
            return f"re-taring: keep the desk still for {scene.profile.estimation.tare_s:g} s"
        if cmd.name == "pause":
            seconds = pause_seconds(cmd.argument) if cmd.argument is not None else MAX_PAUSE_S
            self.paused = self.live.paused = True
            self._paused_until = time.monotonic() + seconds
            return (
                f"paused for {seconds:g} s: gestures are recognised but not sent (sensing and "
                "the zero go on); `resume` ends it sooner"
            )
        if cmd.name == "resume":
            self.paused = self.live.paused = False
            self._paused_until = None
            return "resumed: gestures are sent again"
        if cmd.name == "reload":
            return self._use_layout(Path(scene.context.layout_path or self.layout_path))
        # layout NAME
        assert cmd.argument is not None
        path = self.named_layouts.get(cmd.argument)
        if path is None:
            raise ControlError(
                f"no layout named {cmd.argument!r}; known: {', '.join(sorted(self.named_layouts))}"
                " (name them under `layouts:` in the layout the run started with)"
            )
        return self._use_layout(path, cmd.argument)

    def _use_layout(self, path: Path, name: str | None = None) -> str:
        """Load ``path`` and swap it in: new engine and actions; the same estimator, zero,
        source, event sinks and shared connections."""
        line = self.reloads.prepare(path, name, self._t_last)
        if not self.reloads.take(self._t_last):
            line += "; it takes over when the touch in progress ends"
        return line

    def _end_pause(self) -> None:
        """A pause that reached its length ends by itself (the log says so)."""
        self.paused = self.live.paused = False
        self._paused_until = None
        log.warning("control: the pause ended by itself; gestures are sent again")

    def stop(self, reason: str = "request", *, force: bool = False) -> None:
        """Ask the run to end; ``force`` skips waiting for queued commands."""
        if self.report.stopped_by is None:
            self.report.stopped_by = reason
        self._force = self._force or force
        self._stop.set()
        self.scene.source.close()  # unblocks a source waiting for data or for its pace

    def run(self, *, handle_signals: bool = True) -> RunReport:
        """Sense until the source ends or a stop; returns the report (also on errors)."""
        scene = self.scene
        started = time.monotonic()
        try:
            self.events.open()
            if scene.actions:  # a preview sends nothing: no plugin listens for commands either
                # (the MQTT one had said the desk online, announced it to Home Assistant and
                # said it offline at the end: a design session impersonated the real desk)
                scene.registry.notify(
                    "control_channel",
                    control=scene.control,
                    desk=scene.profile,
                    layout=scene.layout,
                    context=scene.context,
                )
            # (typed: the type checker holds the Runtime to what the hook promises plugins)
            watched: RunView = self
            scene.registry.notify(
                "startup", desk=scene.profile, layout=scene.layout, runtime=watched
            )
        except BaseException:  # an unwritable events file, or --strict and a plugin failed
            self.events.close()
            scene.close()
            raise
        sensing = threading.Thread(target=self._sense_guarded, name="sensing", daemon=True)
        with self._signals(handle_signals):
            sensing.start()
            while sensing.is_alive():
                sensing.join(STATUS_INTERVAL_S)
                self._draw_status()
            self._draw_status(final=True)
            self.events.close()
            if self.events.failure is not None:
                self.report.output_failures.append(self.events.summary())
                self.report.notes.append(self.report.output_failures[-1])
            # queued commands get drain_timeout_s in all: first the actions' own queues, then
            # the shared connections they handed their messages to
            deadline = time.monotonic() + (0.0 if self._force else self.drain_timeout_s)
            self.report.dispatch = scene.dispatcher.close(max(0.0, deadline - time.monotonic()))
            remaining = 0.0 if self._force else max(0.0, deadline - time.monotonic())
            self.report.notes.extend(scene.context.close_resources(remaining))
            self.report.undelivered = scene.context.undelivered
        scene.source.close()
        for cmd, future in scene.control.take():  # asked for after the last block
            future.set_exception(ControlError(f"`{cmd}`: the run has ended"))
        self.report.wall_s = time.monotonic() - started
        scene.registry.notify(
            "shutdown", desk=scene.profile, layout=scene.layout, report=self.report
        )
        return self.report

    # --- the sensing thread -------------------------------------------------------------------

    def _sense_guarded(self) -> None:
        try:
            self._sense()
        except ConfigError as err:  # e.g. a bad line in a replayed file
            self.report.error = str(err)
        except OSError as err:  # e.g. a source's device went away
            where = f"{err.filename}: " if err.filename else ""
            self.report.error = f"{where}{err.strerror or err}"
        except Exception as err:  # a bug: one line for the user, still shut down cleanly
            log.error("sensing stopped by an internal error: %s: %s", type(err).__name__, err)
            log.debug("the internal error's traceback", exc_info=True)  # (-vv shows it)
            self.report.error = f"internal error: {type(err).__name__}: {err}"
        finally:
            # what the source read and rejected (a CAN source's decode statistics)
            self.report.notes.extend(self.scene.source.summary())

    def _sense(self) -> None:
        scene = self.scene
        t_first = t_last = None
        try:
            for block in scene.source.blocks():
                if self._stop.is_set():
                    break
                self.apply_control()  # between blocks: a command never sees half a block
                if self._paused_until is not None and time.monotonic() >= self._paused_until:
                    self._end_pause()
                if len(block.t) == 0:
                    continue
                if t_first is None:
                    t_first = float(block.t[0])
                # (it logs its own notices)
                contacts = scene.estimator.push(block.t, block.wrench, block.accel)
                self._emit(scene.engine.feed(contacts))
                if self.reloads.waiting is not None:  # (at block ends only: never half a touch)
                    self._t_last = float(block.t[-1])
                    self.reloads.take(self._t_last)
                self.live.update(contacts)
                self._tared_once = self._tared_once or self.live.tared
                if scene.observers:
                    scene.observers(contacts, scene.estimator.zero, paused=self.paused)
                for tap in self.block_taps:
                    tap(block.t, block.wrench)
                self.report.samples += len(block.t)
                t_last = self._t_last = float(block.t[-1])
            self.apply_control()
        except BaseException:
            # the source failed (a bad line in a replayed file) or a stage did: what was
            # sensed until then ends as at a normal end — a tap pressed and released is
            # decided and sent — and the error the run reports stays the first one
            try:
                self._end_sensing(t_first, t_last)
            except Exception:
                log.exception("ending the gestures after the error failed")
            raise
        self._end_sensing(t_first, t_last)

    def _end_sensing(self, t_first: float | None, t_last: float | None) -> None:
        """The samples' time span into the report, and the engine flushed at the last one
        (a reloaded layout still waiting for a touch to end is dropped). A run whose zero
        was never taken says so: no gesture could be recognised (a damaged CAN log had ended
        with 0 taps and nothing said)."""
        if t_first is not None and t_last is not None and not self._tared_once:
            self.report.notes.append(
                f"the desk was never tared in {t_last - t_first:.1f} s of samples: no gesture "
                "could be recognised (the tare needs a still desk and whole samples; see the "
                "warnings above)"
            )
        self.reloads.drop()
        if t_first is not None and t_last is not None:
            self.report.sample_time_s = t_last - t_first
            self._emit(self.scene.engine.flush(t_last))

    def _emit(self, events: list[GestureEvent]) -> None:
        if self.paused:  # recognised (the engine's state stays right) but not sent
            return
        for event in events:
            self.events.write(event)
            self.scene.dispatcher.submit(event)
            self.report.gestures[event.gesture] += 1
            self.live.last_gesture = f"{event.action_name} at {event.t:.2f} s"
            self.live.gestures += 1

    # --- the watcher --------------------------------------------------------------------------

    def _draw_status(self, final: bool = False) -> None:
        stream = self.status_stream
        if stream is None:
            return
        stream.write("\r\x1b[K" + self.live.line() + ("\n" if final else ""))
        stream.flush()

    @contextlib.contextmanager
    def _signals(self, enabled: bool) -> Iterator[None]:
        if not enabled:  # (nor from a thread other than the main one: signals_handed_off)
            yield
            return

        def on_signal(signum: int) -> None:
            name = signal.Signals(signum).name
            if self._stop.is_set():
                print(
                    f"\n{name} again: stopping without waiting for queued commands", file=sys.stderr
                )
                self.stop(name, force=True)
            else:
                print(
                    f"\n{name}: stopping (queued commands get {self.drain_timeout_s:g} s; "
                    "again to stop at once)",
                    file=sys.stderr,
                )
                self.stop(name)

        def on_hangup(signum: int) -> None:
            # only queued: the sensing thread reloads between two blocks
            print("\nSIGHUP: reloading the layout", file=sys.stderr)
            self.request("reload")

        # (answered in a thread of their own: a stop set in the handler could wait for good
        # on a lock the main thread held where the signal came, signal_handoff.py)
        work: dict[signal.Signals, Callable[[int], None]] = {
            signal.SIGINT: on_signal,
            signal.SIGTERM: on_signal,
        }
        if hasattr(signal, "SIGHUP"):  # not on Windows
            work[signal.SIGHUP] = on_hangup
        with signals_handed_off(work):
            yield

"""The run loop: source → estimator → gesture engine → dispatcher, until the source ends.

One *sensing* thread reads blocks, estimates contacts, recognises gestures, writes the events
file and hands events to the dispatcher (which never blocks it). The calling thread watches:
it draws the status line and turns SIGINT/SIGTERM into a clean stop. At the end the gesture
engine is flushed (a pending tap is decided), queued commands get a bounded time to go out,
and what did not is reported.

What runs is built by :func:`~hapticdesk.runtime.assembly.build_scene` (re-exported here, as
are ``Assembly``, ``build_routes`` and ``load_scene_layout``); this module names no plugin.
"""

from __future__ import annotations

import collections
import contextlib
import json
import logging
import os
import signal
import sys
import threading
import time
from collections.abc import Iterator
from concurrent.futures import Future
from dataclasses import dataclass, field
from pathlib import Path
from types import FrameType
from typing import IO, Any

from hapticdesk.estimator.contacts import FLAG_NOT_TARED, ContactBlock
from hapticdesk.files.profile import DeskProfile
from hapticdesk.files.yamlfile import ConfigError
from hapticdesk.gestures.event import GestureEvent
from hapticdesk.runtime.assembly import Assembly, build_routes, build_scene, load_scene_layout
from hapticdesk.runtime.control import MAX_PAUSE_S, ControlCommand, ControlError, pause_seconds
from hapticdesk.runtime.dispatcher import DispatchReport
from hapticdesk.runtime.operator_secrets import OperatorSecrets

__all__ = [
    "Assembly",
    "LiveStatus",
    "RunReport",
    "Runtime",
    "build_routes",
    "build_scene",
    "load_scene_layout",
    "report_json",
]

log = logging.getLogger(__name__)

STATUS_INTERVAL_S = 0.1
#: the longest a reloaded layout waits (sample time) for the touch in progress to end
MAX_SWAP_WAIT_S = 30.0


@dataclass
class LiveStatus:
    """What the status line shows; written by the sensing thread, read by the watcher."""

    t: float = 0.0
    in_contact: bool = False
    x: float = 0.0
    y: float = 0.0
    force_n: float = 0.0
    last_gesture: str = ""
    gestures: int = 0
    tared: bool = False
    paused: bool = False
    #: the block's last sample, replaced whole (one assignment, so a reader on another thread
    #: never sees half of one): (t, x or None, y or None, force_n, phase, surface index or -1)
    sample: tuple[float, float | None, float | None, float, int, int] | None = None
    #: how many blocks have been sensed; a reader sees whether ``sample`` is new
    blocks: int = 0

    def line(self) -> str:
        where = f"x {self.x:+.3f} y {self.y:+.3f} m" if self.in_contact else "—"
        tare = "" if self.tared else " (taring: keep the desk still)"
        tare += " (paused: gestures not sent)" if self.paused else ""
        last = self.last_gesture or "none yet"
        return (
            f"t {self.t:7.2f} s  {'●' if self.in_contact else '○'} {where}  "
            f"F {self.force_n:5.1f} N  gestures {self.gestures}  last: {last}{tare}"
        )


@dataclass
class RunReport:
    """What happened in a run."""

    samples: int = 0
    sample_time_s: float = 0.0
    wall_s: float = 0.0
    gestures: collections.Counter[str] = field(default_factory=collections.Counter)
    dispatch: DispatchReport = field(default_factory=DispatchReport)
    notes: list[str] = field(default_factory=list)
    #: optional outputs that could not be written (``--events`` on a full disk), one line each
    output_failures: list[str] = field(default_factory=list)
    #: messages the actions handed to a connection that never delivered them
    undelivered: int = 0
    stopped_by: str | None = None  # a signal's name, or None when the source ended
    error: str | None = None

    @property
    def gesture_count(self) -> int:
        return sum(self.gestures.values())

    def _done(self, ok: int) -> str:
        """The calls that returned: "done" only when their connection delivered everything
        (without a broker the summary had said "57 done" with nothing delivered)."""
        if not self.undelivered:
            return f"{ok} done"
        return (
            f"{ok} handed to their connection, which did NOT deliver {self.undelivered} "
            "message(s) (see below)"
        )

    def summary(self) -> list[str]:
        d = self.dispatch.totals
        if self.stopped_by:
            how = f"stopped by {self.stopped_by}"
        else:  # the error, as the summary's last line, says what failed
            how = "sensing failed" if self.error else "the source ended"  # (source or stage)
        lines = [
            f"{how}: {self.samples} samples ({self.sample_time_s:.2f} s of sensor time) in "
            f"{self.wall_s:.2f} s; {self.gesture_count} gestures"
            + (
                " (" + ", ".join(f"{n} {g}" for g, n in self.gestures.most_common()) + ")"
                if self.gestures
                else ""
            ),
            f"actions: {self._done(d.ok)}, {d.failed} failed, {d.timed_out} timed out, "
            f"{d.dropped} dropped, {d.not_run} not run",
        ]
        return lines + self.notes + ([f"error: {self.error}"] if self.error else [])


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
        self.events_path = Path(events_path) if events_path is not None else None
        self.status_stream = status
        self.drain_timeout_s = drain_timeout_s
        self.live = LiveStatus()
        self.report = RunReport()
        self._stop = threading.Event()
        self._force = False
        self._events_out: IO[str] | None = None
        self._events_error: str | None = None  # why --events could not be written, once
        self._events_written = self._events_unwritten = self._events_bytes = 0
        #: callables given every block's ``(t, wrench)`` on the sensing thread, after the
        #: estimator (a set-up check recording raw samples); each must be O(1): keep a
        #: reference, never copy or wait. Replaced whole (a tuple), never changed in place.
        self.block_taps: tuple[Any, ...] = ()
        #: gestures are recognised but not sent while paused (``pause`` / ``resume``), until
        #: ``_paused_until`` (monotonic time) at the latest
        self.paused = False
        self._paused_until: float | None = None
        self._t_last: float | None = None  # the last sample time sensed (to flush an engine)
        #: a reloaded layout built and waiting for the touch in progress to end
        self._waiting: _WaitingLayout | None = None
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
        from hapticdesk.gestures.engine import GestureEngine

        scene, context = self.scene, self.scene.context
        layout, profile = load_scene_layout(path, scene.registry, scene.desk_override)
        refused = self.operator_secrets.refusal(
            layout.raw,
            Path(path),
            scene.registry,
            "a reload (SIGHUP, `reload` or `layout` on MQTT, a save from the browser UI)",
            "restart the desk to use it",
        )
        if refused is not None:
            raise refused
        if _desk_key(profile) != _desk_key(scene.profile):
            raise ConfigError(
                str(path),
                f"the layout is for desk `{profile.name}` but this run senses desk "
                f"`{scene.profile.name}`; a new desk needs a restart",
            )
        if layout.desk_name != context.desk_name:
            raise ConfigError(
                str(path),
                f"the layout names the desk `{layout.desk_name}` but this run is "
                f"`{context.desk_name}` (its topics and identity); a new name needs a restart",
            )
        for warning in layout.warnings:
            log.warning("%s", warning)
        before = (context.layout, context.settings, context.layout_path)
        context.layout, context.settings, context.layout_path = layout, layout.raw, Path(path)
        try:
            routes = (
                build_routes(layout, scene.registry, context, scene.action_timeout_s)
                if scene.actions
                else []
            )
            engine = GestureEngine(
                layout,
                recognizer_types=scene.registry.recognizer_types(),
                position_delay_s=scene.estimator.position_delay_s,
            )
        except BaseException:
            context.layout, context.settings, context.layout_path = before
            raise
        what = f"layout `{name}` ({path})" if name else f"reloaded {path}"
        line = f"{what}: {len(layout.bindings)} bindings; the zero and connections are kept"
        # shared connections were opened from the first layout's sections and are kept
        changed = [
            f"`{section}:`"
            for section in scene.registry.layout_sections
            if before[1].get(section) != layout.raw.get(section)
        ]
        if changed:
            line += (
                f" ({', '.join(changed)} changed: its connection settings take effect at the "
                "next start)"
            )
        if self._waiting is not None:  # a newer layout replaces one still waiting
            _close_routes(self._waiting.routes)
        self._waiting = _WaitingLayout(layout, engine, routes, self._t_last)
        if not self._take_waiting_layout():
            line += "; it takes over when the touch in progress ends"
        return line

    def _take_waiting_layout(self) -> bool:
        """Swap in the layout a reload built, if any, once the running engine is idle: a
        touch finishes under the layout it began in (a reload during a 3 s hold had fired a
        second long press, and a toggle bound to it twice). A touch still held
        :data:`MAX_SWAP_WAIT_S` of sample time after the reload is cancelled (phase
        `cancel`, never a release) and the new layout taken. True when swapped (or nothing
        waited)."""
        waiting, scene = self._waiting, self.scene
        if waiting is None:
            return True
        if not scene.engine.idle:
            asked, now = waiting.asked_t, self._t_last
            if asked is None or now is None or now - asked < MAX_SWAP_WAIT_S:
                return False
            log.warning(
                "control: a touch was still held %g s after the reload; it is cancelled and "
                "the new layout taken",
                MAX_SWAP_WAIT_S,
            )
            self._emit(scene.engine.cancel(now))
            waiting.engine.join_contact()  # (the held finger is nobody's new touch)
        if self._t_last is not None:  # what the old layout was deciding is decided
            self._emit(scene.engine.flush(self._t_last))
        scene.estimator.use_second_finger(
            scene.profile.estimation.second_finger or waiting.engine.needs_second_finger
        )
        scene.dispatcher.replace_routes(waiting.routes, self.drain_timeout_s)
        scene.engine, scene.layout = waiting.engine, waiting.layout
        self._waiting = None
        return True

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
            self._events_out = self._open_events()
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
            scene.registry.notify("startup", desk=scene.profile, layout=scene.layout, runtime=self)
        except BaseException:  # an unwritable events file, or --strict and a plugin failed
            if self._events_out is not None:
                self._events_out.close()
            scene.close()
            raise
        sensing = threading.Thread(target=self._sense_guarded, name="sensing", daemon=True)
        with self._signals(handle_signals):
            sensing.start()
            while sensing.is_alive():
                sensing.join(STATUS_INTERVAL_S)
                self._draw_status()
            self._draw_status(final=True)
            if self._events_out is not None:
                try:
                    self._events_out.close()
                except OSError as err:  # (what was left in its buffer: the disk is full)
                    self._events_lost(err)
                self._events_out = None
            if self._events_error is not None:
                self.report.output_failures.append(self._events_summary())
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
                if self._waiting is not None:  # (at block ends only: never half a touch)
                    self._t_last = float(block.t[-1])
                    self._take_waiting_layout()
                self._update_live(contacts)
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
        if self._waiting is not None:
            _close_routes(self._waiting.routes)
            self._waiting = None
        if t_first is not None and t_last is not None:
            self.report.sample_time_s = t_last - t_first
            self._emit(self.scene.engine.flush(t_last))

    def _emit(self, events: list[GestureEvent]) -> None:
        if self.paused:  # recognised (the engine's state stays right) but not sent
            return
        for event in events:
            self._write_event(event)
            self.scene.dispatcher.submit(event)
            self.report.gestures[event.gesture] += 1
            self.live.last_gesture = f"{event.action_name} at {event.t:.2f} s"
            self.live.gestures += 1

    def _write_event(self, event: GestureEvent) -> None:
        """One line of ``--events``. The file is optional: when it cannot be written (a full
        disk, a quota) it is said once, cut back to its last whole line and dropped, and the
        events not written are counted; sensing and the actions go on (a full disk had
        stopped the desk)."""
        if self._events_out is None:
            if self._events_error is not None:
                self._events_unwritten += 1
            return
        line = event.to_json() + "\n"
        try:
            self._events_out.write(line)
            self._events_out.flush()
        except OSError as err:  # (a full disk: /dev/full, a quota)
            self._events_lost(err)
            self._events_unwritten += 1
            return
        self._events_written += 1
        self._events_bytes += len(line.encode("utf-8"))

    def _events_lost(self, err: OSError) -> None:
        """``--events`` failed: said once, its last half line cut off, the file dropped."""
        if self._events_error is None:
            self._events_error = err.strerror or str(err)
            log.error(
                "%s: cannot write the events (%s); sensing and the actions go on, the "
                "events from now on are not written",
                self.events_path,
                self._events_error,
            )
        out, self._events_out = self._events_out, None
        if out is not None:
            try:
                out.close()
            except OSError:
                pass  # (its buffer could not be written either)
        try:  # a reader finds whole events only
            if self.events_path is not None and self.events_path.is_file():
                os.truncate(self.events_path, self._events_bytes)
        except OSError:
            pass

    def _events_summary(self) -> str:
        return (
            f"{self.events_path}: cannot write the events ({self._events_error}): "
            f"{self._events_written} written (whole lines), {self._events_unwritten} not"
        )

    def _update_live(self, contacts: ContactBlock) -> None:
        live = self.live
        live.t = float(contacts.t[-1])
        live.in_contact = bool(contacts.in_contact[-1])
        live.force_n = float(contacts.force_n[-1])
        if contacts.located[-1]:
            live.x, live.y = float(contacts.x[-1]), float(contacts.y[-1])
        live.tared = not bool(contacts.flags[-1] & FLAG_NOT_TARED)
        self._tared_once = self._tared_once or live.tared
        located = bool(contacts.located[-1])
        live.sample = (
            live.t,
            float(contacts.x[-1]) if located else None,
            float(contacts.y[-1]) if located else None,
            live.force_n,
            int(contacts.phase[-1]),
            int(contacts.surface[-1]),
        )
        live.blocks += 1

    # --- the watcher --------------------------------------------------------------------------

    def _draw_status(self, final: bool = False) -> None:
        stream = self.status_stream
        if stream is None:
            return
        stream.write("\r\x1b[K" + self.live.line() + ("\n" if final else ""))
        stream.flush()

    def _open_events(self) -> IO[str] | None:
        if self.events_path is None:
            return None
        try:
            return self.events_path.open("w", encoding="utf-8")
        except OSError as err:
            raise ConfigError(
                "--events", f"cannot write {self.events_path}: {err.strerror}"
            ) from None

    @contextlib.contextmanager
    def _signals(self, enabled: bool) -> Iterator[None]:
        if not enabled or threading.current_thread() is not threading.main_thread():
            yield
            return

        def on_signal(signum: int, frame: FrameType | None) -> None:
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

        def on_hangup(signum: int, frame: FrameType | None) -> None:
            # only queued: the sensing thread reloads between two blocks
            print("\nSIGHUP: reloading the layout", file=sys.stderr)
            self.request("reload")

        previous = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
        if hasattr(signal, "SIGHUP"):  # not on Windows
            previous[signal.SIGHUP] = signal.signal(signal.SIGHUP, on_hangup)
        try:
            yield
        finally:
            for s, handler in previous.items():
                signal.signal(s, handler)


@dataclass
class _WaitingLayout:
    """A reloaded layout, built and checked, waiting for the running engine to be idle."""

    layout: Any
    engine: Any
    routes: list[Any]
    asked_t: float | None  # the sample time of the reload


def _close_routes(routes: list[Any]) -> None:
    for route in routes:
        for lane in route.lanes:
            lane.close(0.0)


def _desk_key(profile: DeskProfile) -> tuple[Any, ...]:
    """What makes two profiles the same desk for a running estimator."""
    return (profile.name, profile.sample_rate_hz, tuple(s.name for s in profile.sensors))


def report_json(report: RunReport) -> str:
    """The report as one JSON object (for scripts)."""
    d = report.dispatch.totals
    return json.dumps(
        {
            "samples": report.samples,
            "sample_time_s": round(report.sample_time_s, 6),
            "wall_s": round(report.wall_s, 3),
            "gestures": dict(report.gestures),
            "actions": {
                "ok": d.ok,
                "failed": d.failed,
                "timed_out": d.timed_out,
                "dropped": d.dropped,
                "not_run": d.not_run,
                "undelivered": report.undelivered,
            },
            "notes": report.notes,
            "stopped_by": report.stopped_by,
            "error": report.error,
        }
    )

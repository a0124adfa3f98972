"""The feed: a thread that reads the attached run and hands what changed to the hub.

Nothing here runs on the sensing thread. :data:`CONTACT_RATE_HZ` times a second, while a page
is open, the feed reads the run's latest contact sample (which the sensing thread copies once
per block into ``runtime.live``, O(1)), the estimator's new notices and the actions' counts,
and publishes what changed.
"""

from __future__ import annotations

import threading
import time
from typing import TYPE_CHECKING

from hapticdesk.plugins.ui.hub import Hub, notice_message
from hapticdesk.plugins.ui.shown_desk import ShownDesk

if TYPE_CHECKING:
    from hapticdesk.runtime.service import Runtime

#: contact frames per second sent to each browser (the page draws at most at this rate)
CONTACT_RATE_HZ = 50.0
#: the contact phase codes of `runtime.live.sample`, as the page names them
CONTACT_PHASES = ("", "touch", "hold", "release")


class Feed:
    """Reads ``shown``'s run and publishes to ``hub`` on a thread of its own until
    :meth:`close`."""

    def __init__(self, shown: ShownDesk, hub: Hub) -> None:
        self.shown = shown
        self.hub = hub
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, name="ui feed", daemon=True)
        self._runtime_seen: Runtime | None = None
        self._seen_blocks = -1
        self._seen_notices = 0
        self._lane_counts: dict[int, tuple[int, int, int, int]] = {}

    def start(self) -> None:
        self._thread.start()

    def close(self) -> None:
        """Stop (idempotent; the thread ends at its next beat)."""
        self._stop.set()

    def _loop(self) -> None:
        period = 1.0 / CONTACT_RATE_HZ
        tick = time.monotonic()
        # on a fixed beat (not a sleep after the work), so a busy machine does not slow it more
        while not self._stop.wait(max(0.0, tick + period - time.monotonic())):
            tick = max(tick + period, time.monotonic() - period)
            runtime = self.shown.runtime
            if runtime is None or not self.hub.clients:
                continue  # nothing is read while no browser is connected
            if runtime is not self._runtime_seen:
                self._runtime_seen, self._seen_blocks, self._lane_counts = runtime, -1, {}
                self._seen_notices = runtime.scene.estimator.notices.total
            self._contact(runtime)
            self._notices(runtime)
            self._actions(runtime)

    def _contact(self, runtime: Runtime) -> None:
        """The latest contact sample, when a block came since the last one sent."""
        live = runtime.live
        blocks, sample = live.blocks, live.sample
        if sample is None or blocks == self._seen_blocks:
            return
        self._seen_blocks = blocks
        t, x, y, force, phase, surface = sample
        profile = runtime.scene.profile
        self.hub.publish(
            {
                "type": "contact",
                "t": round(t, 4),
                "x": None if x is None else round(x, 5),
                "y": None if y is None else round(y, 5),
                "force_n": round(force, 3),
                "phase": CONTACT_PHASES[phase] if 0 <= phase < len(CONTACT_PHASES) else "",
                "surface": profile.surfaces[surface].name if surface >= 0 else None,
                "tared": live.tared,
                "paused": live.paused,  # (gestures not sent: the page says so)
            }
        )

    def _notices(self, runtime: Runtime) -> None:
        """What the estimator said since the last beat."""
        notices = runtime.scene.estimator.notices
        for notice in notices.since(self._seen_notices):
            self.hub.publish(notice_message(notice))
        self._seen_notices = notices.total

    def _actions(self, runtime: Runtime) -> None:
        """Each action lane's counts, when they changed."""
        for lane in (ln for route in runtime.scene.dispatcher.routes for ln in route.lanes):
            s = lane.stats
            counts = (s.ok, s.failed, s.timed_out, s.dropped)
            if self._lane_counts.get(id(lane), (0, 0, 0, 0)) == counts:
                continue
            self._lane_counts[id(lane)] = counts
            self.hub.publish(
                {
                    "type": "action",
                    "label": lane.label,
                    "ok": s.ok,
                    "failed": s.failed,
                    "timed_out": s.timed_out,
                    "dropped": s.dropped,
                }
            )

"""What a run did: samples, gestures, the actions' counts and what did not go out, as lines
for a person (:meth:`RunReport.summary`) and as one JSON object for scripts
(:func:`report_json`)."""

from __future__ import annotations

import collections
import json
from dataclasses import dataclass, field

from hapticdesk.runtime.dispatcher import DispatchReport


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

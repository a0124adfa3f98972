"""A CAN log decoded into a desk's samples through the profile's ``can:`` section: whole
(:func:`read_can_log`, a :class:`~hapticdesk.files.recording.Recording`, with
:func:`decode_can_log` the statistics too) or chunk by chunk as a finite source
(:func:`open_can_log`, for a replay). ATI boards' calibrations the profile does not give
are taken from the replies recorded in the log."""

from __future__ import annotations

import logging
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from hapticdesk.canbus.assembler import AssembledBlock, FrameAssembler
from hapticdesk.canbus.ati_netcanoem import AtiCalibration, CalibrationCollector, ati_frame_ids
from hapticdesk.canbus.config import CanConfig
from hapticdesk.canbus.config_reader import can_config
from hapticdesk.canbus.decoding import build_decoding
from hapticdesk.canbus.logs.formats import read_frames
from hapticdesk.canbus.stats import CanNotice, CanStats
from hapticdesk.errors import ConfigError
from hapticdesk.files.profile import DeskProfile
from hapticdesk.files.recording import Recording
from hapticdesk.runtime.source import Source, WrenchBlock

log = logging.getLogger(__name__)

#: in a log assembled by counter, a channel whose frame is missing holds its value this many
#: samples at most (:class:`~hapticdesk.canbus.field_hold.FieldHold`): a corrupt line loses
#: one frame, not the sample
HOLD_SAMPLES = 2


@dataclass
class CanLogDecoding:
    """What decoding a log gave: the samples and what was seen on the way."""

    recording: Recording
    stats: CanStats
    notices: list[CanNotice] = field(default_factory=list)


def log_calibrations(path: str | Path, config: CanConfig) -> dict[str, AtiCalibration]:
    """Calibrations of the ATI boards the profile gives none for, from the replies in a log."""
    wanted = {n: s for n, s in config.ati_sensors.items() if s.calibration is None}
    if not wanted:
        return {}
    collectors = {n: CalibrationCollector(s.base) for n, s in wanted.items()}
    ids = np.array(sorted(set().union(*(ati_frame_ids(s.base) for s in wanted.values()))))
    for chunk in read_frames(path):
        sel = np.flatnonzero(np.isin(chunk.ident, ids))
        idents = chunk.ident[sel].tolist()
        dlcs = chunk.dlc[sel].tolist()
        for j, i in enumerate(sel.tolist()):
            payload = chunk.data[i, : dlcs[j]].tobytes()
            for c in collectors.values():
                c.feed(idents[j], payload)
        if all(c.calibration() is not None for c in collectors.values()):
            break
    out = {}
    for name, c in collectors.items():
        cal = c.calibration()
        if cal is None:
            hint = " (row replies without their requests)" if c.unpaired_rows else ""
            raise ConfigError(
                str(path),
                f"ATI sensor `{name}` (base 0x{c.base:02X}): the log lacks "
                f"{', '.join(c.missing()) or 'a usable matrix'}{hint}; record the start-up "
                "exchange with `hapticdesk record`, or give `calibration` in the profile",
            )
        if c.units is None:
            log.warning("ATI sensor %s: the log has no units reply (0x8); assuming N and N·m", name)
        out[name] = cal
    return out


def _assembler(path: str | Path, profile: DeskProfile) -> FrameAssembler:
    config = can_config(profile)
    decoding = build_decoding(config, profile, log_calibrations(path, config))
    return FrameAssembler(
        decoding,
        profile.sample_rate_hz,
        assemble=config.assemble,
        frame_gap_s=config.frame_gap_s,
        silent_timeout_s=config.silent_timeout_s,
        silent_sensor=config.silent_sensor,
        where=str(path),
        # by counter a sample's frames are known for sure, so a lost one is a known hole;
        # by time, an incomplete sample may be frames split wrongly, and nothing is held
        hold_samples=HOLD_SAMPLES if config.assemble == "counter" else 0,
    )


def _blocks(
    path: str | Path, assembler: FrameAssembler, skipped: dict[str, int] | None = None
) -> Iterator[AssembledBlock]:
    for chunk in read_frames(path, skipped=skipped):
        block = assembler.push(chunk)
        yield block
        if block.stop is not None:
            raise block.stop
    block = assembler.flush()
    yield block
    if block.stop is not None:
        raise block.stop


def decode_can_log(path: str | Path, profile: DeskProfile) -> CanLogDecoding:
    """Decode a whole log into a Recording, with the statistics of what was in it."""
    assembler = _assembler(path, profile)
    ts, ws, accs = [], [], []
    for block in _blocks(path, assembler):
        ts.append(block.t)
        ws.append(block.wrench)
        if block.accel is not None:
            accs.append(block.accel)
    t = np.concatenate(ts)
    if not len(t):
        raise _nothing_decoded(Path(path), profile.name, assembler.stats)
    extra = {}
    if accs and profile.accelerometer is not None:  # the columns a recording would have
        accel = np.concatenate(accs)
        extra = {c: accel[:, i] for i, c in enumerate(profile.accelerometer_columns())}
    recording = Recording(t, np.concatenate(ws), profile.sensor_names, extra)
    return CanLogDecoding(recording, assembler.stats, list(assembler.notices))


def _nothing_decoded(path: Path, desk: str, stats: CanStats) -> ConfigError:
    """No sample decoded: say what the frames were instead."""
    reasons = stats.summary()[1:]
    if stats.data_frames or stats.wrong_length:
        why = "; ".join(reasons) or "no frame kind complete"
    else:
        why = f"none with the identifiers its `can:` section decodes ({'; '.join(reasons)})"
    return ConfigError(
        str(path), f"no samples of desk `{desk}` in this log: {stats.frames} frames, {why}"
    )


def read_can_log(path: str | Path, profile: DeskProfile) -> Recording:
    """A CAN log decoded through the profile's ``can:`` section (problems logged as warnings)."""
    result = decode_can_log(path, profile)
    lines = result.stats.summary()
    if len(lines) > 1:
        log.warning("%s: %s", path, "; ".join(lines))
    return result.recording


class CanLogSource(Source):
    """A CAN log as a finite source of wrench blocks, decoded chunk by chunk."""

    def __init__(self, path: str | Path, profile: DeskProfile) -> None:
        self.path = Path(path)
        self.profile_name = profile.name
        self.assembler = _assembler(path, profile)
        super().__init__(
            profile.sensor_names, profile.sample_rate_hz, channel_count=profile.channel_count
        )
        self._assembled: Iterator[AssembledBlock] | None = None
        #: lines and frames the reader skipped, by reason (see :func:`read_frames`)
        self.skipped: dict[str, int] = {}

    @property
    def stats(self) -> CanStats:
        return self.assembler.stats

    def summary(self) -> list[str]:
        lines = self.stats.summary()
        lines[1:1] = [f"{n} {what} skipped" for what, n in self.skipped.items()]
        return [f"CAN log {self.path.name}: {line}" for line in lines]

    def read_block(self) -> WrenchBlock | None:
        """The samples of the log's next chunk of frames; None at its end."""
        if self._assembled is None:
            self._assembled = _blocks(self.path, self.assembler, self.skipped)
        block = next(self._assembled, None)
        if block is None:
            if not self.stats.samples:
                raise _nothing_decoded(self.path, self.profile_name, self.stats)
            return None
        return WrenchBlock(block.t, block.wrench, accel=block.accel)

    def release(self) -> None:
        close = getattr(self._assembled, "close", None)  # the log file's reader
        if close is not None:
            close()


def open_can_log(path: str | Path, profile: DeskProfile) -> Source:
    """A finite :class:`~hapticdesk.runtime.source.Source` of the log's samples."""
    return CanLogSource(path, profile)

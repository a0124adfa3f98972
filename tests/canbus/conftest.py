"""Fixtures for the CAN tests: the shipped CAN profiles, samples to encode, helpers."""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from hapticdesk.canbus.assembler import FrameAssembler
from hapticdesk.canbus.config import CanConfig
from hapticdesk.canbus.config_reader import can_config
from hapticdesk.canbus.decoding import build_decoding
from hapticdesk.canbus.emulator import CanEmulator
from hapticdesk.canbus.frame_encoder import FrameEncoder
from hapticdesk.canbus.frames import FrameArray
from hapticdesk.files.profile import DeskProfile
from hapticdesk.files.profile_reader import load_profile, profile_from_mapping
from hapticdesk.files.yamlfile import load_marked_yaml


@pytest.fixture(scope="session")
def can_desk() -> DeskProfile:
    """The paper's desk read over CAN (profiles/kitamura2017-can.yaml, its DBC)."""
    return load_profile("kitamura2017-can")


@pytest.fixture(scope="session")
def bench() -> DeskProfile:
    """One ATI board on the bench (profiles/ati-bench.yaml)."""
    return load_profile("ati-bench")


@pytest.fixture
def profile_text(tmp_path: Path) -> Callable[[str], DeskProfile]:
    """Load a profile from YAML text written next to a copy of the shipped DBC."""
    dbc = Path(str(load_profile("kitamura2017-can").path)).with_name("kitamura2017.dbc")
    (tmp_path / "kitamura2017.dbc").write_bytes(dbc.read_bytes())

    def load(text: str, name: str = "desk.yaml") -> DeskProfile:
        path = tmp_path / name
        path.write_text(text, encoding="utf-8")
        return profile_from_mapping(load_marked_yaml(path), path)

    return load


LEGS = """name: {name}
sample_rate_hz: 1200
sensors:
  - {{name: fl, position: [-0.34, -0.22, 0.0]}}
  - {{name: fr, position: [0.34, -0.22, 0.0]}}
  - {{name: bl, position: [-0.34, 0.22, 0.0]}}
  - {{name: br, position: [0.34, 0.22, 0.0]}}
surfaces:
  - {{name: top, origin: [0, 0, 0.733], normal: [0, 0, 1],
     polygon: [[-0.375, -0.25], [0.375, -0.25], [0.375, 0.25], [-0.375, 0.25]]}}
"""


@pytest.fixture
def ati_desk(profile_text: Callable[[str, str], DeskProfile]) -> tuple[DeskProfile, CanConfig]:
    """The paper's desk on four ATI boards at bases 0x20…0x23 (assembled by polls)."""
    text = (
        LEGS.format(name="ati-desk")
        + "can:\n  sensors:\n"
        + "".join(
            f"    {n}: {{ati_netcanoem: {{base: 0x2{i}}}}}\n"
            for i, n in enumerate(("fl", "fr", "bl", "br"))
        )
    )
    profile = profile_text(text, "ati-desk.yaml")
    return profile, can_config(profile)


@pytest.fixture
def uncounted_desk(profile_text: Callable[[str, str], DeskProfile]) -> DeskProfile:
    """The shipped DBC desk without its counters: assembled by time."""
    text = (
        LEGS.format(name="uncounted")
        + "can:\n  database: kitamura2017.dbc\n  sensors:\n"
        + "".join(
            f"    {n}: {{fx: {m}_FORCE.Fx, fy: {m}_FORCE.Fy, fz: {m}_FORCE.Fz, "
            f"mx: {m}_MOMENT.Mx, my: {m}_MOMENT.My, mz: {m}_MOMENT.Mz}}\n"
            for n, m in (("fl", "FL"), ("fr", "FR"), ("bl", "BL"), ("br", "BR"))
        )
    )
    return profile_text(text, "uncounted.yaml")


def samples(
    n: int, sensors: int, seed: int = 0, rate: float = 1200.0
) -> tuple[np.ndarray, np.ndarray]:
    """``n`` samples of plausible leg readings: ~34 N of desk weight each, noise, moments."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / rate
    wrench = rng.normal(0.0, 2.0, (n, sensors, 6))
    wrench[:, :, 2] += 34.0
    wrench[:, :, 3:] *= 0.02
    return t, wrench


@pytest.fixture
def make_samples() -> Callable[..., tuple[np.ndarray, np.ndarray]]:
    return samples


def assemble(
    profile: DeskProfile,
    config: CanConfig,
    frames: FrameArray,
    calibrations: dict | None = None,
    *,
    chunks: int = 1,
    **options: object,
) -> tuple[np.ndarray, np.ndarray, FrameAssembler]:
    """Push ``frames`` in ``chunks`` equal pieces and flush: (t, wrench, assembler).

    Raises the assembler's stop error (a silent sensor with ``silent_sensor="stop"``).
    """
    decoding = build_decoding(config, profile, calibrations)
    kwargs = {
        "assemble": config.assemble,
        "frame_gap_s": config.frame_gap_s,
        "silent_timeout_s": config.silent_timeout_s,
        "silent_sensor": config.silent_sensor,
    }
    kwargs.update(options)
    asm = FrameAssembler(decoding, profile.sample_rate_hz, **kwargs)  # type: ignore[arg-type]
    ts, ws = [], []
    bounds = np.linspace(0, len(frames), chunks + 1).astype(int)
    for a, b in zip(bounds[:-1], bounds[1:], strict=True):
        out = asm.push(frames.take(slice(a, b)))
        if out.stop is not None:
            raise out.stop
        ts.append(out.t)
        ws.append(out.wrench)
    out = asm.flush()
    ts.append(out.t)
    ws.append(out.wrench)
    return np.concatenate(ts), np.concatenate(ws), asm


@pytest.fixture
def run_assembler() -> Callable[..., tuple[np.ndarray, np.ndarray, FrameAssembler]]:
    return assemble


@pytest.fixture
def dbc_frames(can_desk: DeskProfile) -> Callable[..., tuple[np.ndarray, np.ndarray, FrameArray]]:
    """Samples and their frames for the shipped DBC desk."""
    encoder = FrameEncoder(can_config(can_desk), can_desk)

    def make(
        n: int = 600, seed: int = 0, **options: object
    ) -> tuple[np.ndarray, np.ndarray, FrameArray]:
        t, wrench = samples(n, 4, seed)
        return t, wrench, encoder.encode(t, wrench, **options)  # type: ignore[arg-type]

    return make


@pytest.fixture(scope="session")
def dbc_tolerance() -> np.ndarray:
    """Half a least significant bit of the shipped DBC: force 0.01 N, moment 0.0002 N·m."""
    return np.array([0.005, 0.005, 0.005, 0.0001, 0.0001, 0.0001]) * (1 + 1e-9)


def canopen_frames(n: int, t_end: float, seed: int = 0, t0: float = 0.0) -> FrameArray:
    """NMT, SYNC, EMCY, PDOs, SDOs and heartbeats of a few CANopen drives, as on a real bus."""
    rng = np.random.default_rng(seed)
    ids = np.array(
        [0x000, 0x080, 0x081, 0x0A3, 0x181, 0x185, 0x201, 0x281, 0x381, 0x581, 0x601, 0x701, 0x705]
    )
    ident = rng.choice(ids, n)
    lengths = np.where(ident == 0x080, 0, np.where(ident >= 0x701, 1, rng.integers(1, 9, n)))
    data = [bytes(rng.integers(0, 256, int(k), dtype=np.uint8)) for k in lengths]
    return FrameArray.build(t0 + np.sort(rng.uniform(0, t_end, n)), ident, data)


@pytest.fixture
def canopen_traffic() -> Callable[..., FrameArray]:
    return canopen_frames


@pytest.fixture
def virtual_channel(request: pytest.FixtureRequest) -> str:
    """A python-can virtual channel of this test alone, so that tests never hear each other."""
    return f"hapticdesk-{request.node.nodeid}"


@dataclass
class BenchBoard:
    """The bench's ATI board emulated on a virtual channel (a thread), at ``profile``'s rate."""

    profile: DeskProfile
    wrench: np.ndarray  # (n, 1, 6) what the board sends, one sample per poll
    emulator: CanEmulator
    thread: threading.Thread
    bus: Any

    def stop(self) -> None:
        self.emulator.stop()
        self.thread.join(2)
        self.bus.shutdown()


@pytest.fixture
def bench_board(
    bench: DeskProfile, profile_text: Callable[[str, str], DeskProfile], virtual_channel: str
) -> Callable[..., BenchBoard]:
    """Start the bench's board at ``rate`` Hz with ``n`` samples of random load (``seed``)."""

    def start(rate: int, n: int, seed: int) -> BenchBoard:
        import can

        text = Path(str(bench.path)).read_text()
        profile = profile_text(
            text.replace("sample_rate_hz: 500", f"sample_rate_hz: {rate}"), "bench.yaml"
        )
        wrench = np.random.default_rng(seed).normal(0, 20, (n, 1, 6))
        wrench[:, :, 3:] *= 0.02
        bus = can.Bus(interface="virtual", channel=virtual_channel)
        encoder = FrameEncoder(can_config(profile), profile)
        emulator = CanEmulator(encoder, np.arange(n) / rate, wrench, bus)
        return BenchBoard(profile, wrench, emulator, emulator.start(), bus)

    return start

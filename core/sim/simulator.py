"""Run a scene on a simulated desk: loads → desk dynamics → sensors → a recording or a source.

The run is computed in fixed chunks of :data:`CHUNK` samples. Each chunk's sensor noise comes
from its own generator (spawned from the seed and the chunk's index) and the desk's state is
carried from chunk to chunk, so :func:`simulate` and :class:`SimSource` give the same samples
for any block size, and a seed gives the same run every time.

A desk of six-axis sensors is sampled at its rate (:mod:`.sensors`). A desk of other sensors
(load cells, three-axis cells: :mod:`.loadcells`) is simulated on a finer grid, each reading
averaging its own conversion, and delivers its raw channels (k, C).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, fields, replace
from typing import NamedTuple

import numpy as np

from hapticdesk.errors import ConfigError
from hapticdesk.files.profile import DeskProfile
from hapticdesk.files.recording import Recording, accel_table
from hapticdesk.runtime.source import Source, WrenchBlock
from hapticdesk.sim.desk import DeskModel, DeskParameters
from hapticdesk.sim.loadcells import Conversions, LoadCellModel, LoadCellParameters, oversampling
from hapticdesk.sim.scene import Scene
from hapticdesk.sim.sensors import AccelerometerModel, SensorModel, SensorParameters
from hapticdesk.sim.timeline import (
    STREAM_ACCEL,
    STREAM_CLOCKS,
    STREAM_DRIFT,
    STREAM_NOISE,
    TRUTH_COLUMNS,
    Timeline,
    stream,
)

CHUNK = 4096  # samples per internal chunk (noise streams are per chunk)
#: the most samples :func:`simulate` makes: it holds them all (the chunks, then the joined
#: recording, then the table a CSV is written from): 1.15 GB peak for 1.92 million samples of
#: the paper desk (four sensors); 28 min at 1.2 kHz. `run --source sim:` streams instead.
MAX_SIMULATE_SAMPLES = 2_000_000


@dataclass(frozen=True)
class SimEffects:
    """Which physical effects a run includes; switch any off for tests.

    ``dynamics`` off: the desk answers every load at once (statics only). ``desk_weight``
    off: the desk itself weighs nothing (objects put on it still do).
    """

    dynamics: bool = True
    noise: bool = True
    drift: bool = True
    quantisation: bool = True
    saturation: bool = True
    desk_weight: bool = True

    @classmethod
    def ideal(cls) -> SimEffects:
        """Statics only, perfect sensors: readings equal the load split exactly (the desk
        still weighs what it weighs)."""
        return cls(**{f.name: f.name == "desk_weight" for f in fields(cls)})


class DeskSamples(NamedTuple):
    """A stretch of the timeline on the desk."""

    loads: np.ndarray  #: (k, 6) about the origin, the desk's weight included
    truth: dict[str, np.ndarray]  #: the ground-truth columns
    true: np.ndarray  #: the sensors' true readings (k, S, 6)
    motion: np.ndarray | None  #: the desk's motion [q, q̇] (k, 12) where an accelerometer needs it
    state: np.ndarray | None  #: the desk's state to carry to the next stretch


class SimulationRun:
    """One run of a scene on a desk with a seed; produces chunks on demand."""

    def __init__(
        self,
        profile: DeskProfile,
        scene: Scene,
        seed: int | None = None,
        *,
        noise: bool = True,
        effects: SimEffects | None = None,
        desk: DeskParameters | None = None,
        sensors: SensorParameters | None = None,
        cells: LoadCellParameters | None = None,
    ) -> None:
        effects = effects or SimEffects()
        if not noise:  # no random sensor error: noise, offset and drift
            effects = replace(effects, noise=False, drift=False)
        self.profile = profile
        self.scene = scene
        self.seed = int(scene.seed if seed is None else seed)
        self.effects = effects
        self.fs = float(profile.sample_rate_hz)
        self.model = DeskModel(profile, desk)
        #: the load cells' model (a desk of sensors other than six-axis ones), else None
        self.cells: LoadCellModel | None = None
        if profile.six_axis_only:
            self._on_six_axis_sensors(sensors, cells)
        else:
            self._on_load_cells(sensors, cells)
        self._base = self.model.weight() if effects.desk_weight else np.zeros(6)
        drift_model = self.cells if self.cells is not None else self.sensor_model
        self._drift = (
            drift_model.draw_drift(stream(self.seed, STREAM_DRIFT)) if effects.drift else None
        )
        self._discrete = self.model.discretize(1.0 / self.timeline.fs) if effects.dynamics else None
        self.accelerometer = AccelerometerModel(profile) if profile.accelerometers else None
        #: the per-sample columns of :meth:`chunks`' third item: the ground truth, then the
        #: accelerometers' readings when the desk has some (recordings' extra columns)
        self.columns: tuple[str, ...] = TRUTH_COLUMNS + tuple(profile.accelerometer_columns())

    def _on_six_axis_sensors(
        self, sensors: SensorParameters | None, cells: LoadCellParameters | None
    ) -> None:
        """The timeline at the desk's rate and the six-axis sensors' model."""
        profile = self.profile
        if cells is not None:
            raise ValueError(
                f"desk {profile.name!r} stands on six-axis sensors: give `sensors` "
                "(SensorParameters), not `cells`"
            )
        self.timeline = Timeline(profile, self.scene, self.seed)
        self.sensor_model = SensorModel(profile, sensors, quantisation=self.effects.quantisation)
        self.n_samples = self.timeline.n_samples

    def _on_load_cells(
        self, sensors: SensorParameters | None, cells: LoadCellParameters | None
    ) -> None:
        """The load cells' model with their conversions and the timeline on the finer grid
        the conversions average."""
        profile = self.profile
        if sensors is not None:
            raise ValueError(
                f"desk {profile.name!r} has sensors other than six-axis ones: give `cells` "
                "(LoadCellParameters), not `sensors`"
            )
        cells = cells or LoadCellParameters.for_rate(self.fs)
        points = oversampling(self.fs, profile.channel_count, cells.sampling)
        conversions = Conversions.of(
            cells.sampling,
            profile.channel_count,
            points,
            cells.clock_tolerance,
            stream(self.seed, STREAM_CLOCKS),
        )
        self.cells = LoadCellModel(profile, cells, conversions)
        fine = replace(profile, sample_rate_hz=self.fs * points)
        self.timeline = Timeline(fine, self.scene, self.seed)
        self.n_samples = (self.timeline.n_samples - 1) // points + 1

    def chunks(self) -> Iterator[tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]]:
        """Yield ``(t, wrench, columns)`` chunk by chunk, from the start: ``columns`` maps
        each of :attr:`columns` to its values; ``wrench`` is (k, S, 6) for a desk of six-axis
        sensors, else the raw channels (k, C)."""
        if self.cells is not None:
            yield from self._cell_chunks(self.cells)
            return
        state = None
        for c, k0 in enumerate(range(0, self.n_samples, CHUNK)):
            k1 = min(k0 + CHUNK, self.n_samples)
            desk = self._desk(k0, k1, state)
            state, truth = desk.state, desk.truth
            t = np.arange(k0, k1) / self.fs
            if self.accelerometer is not None:
                truth.update(self._accelerometer(desk.loads, desk.motion, c))
            wrench = self.sensor_model.apply(
                desk.true,
                t,
                noise_rng=stream(self.seed, STREAM_NOISE, c) if self.effects.noise else None,
                drift=self._drift,
                quantisation=self.effects.quantisation,
                saturation=self.effects.saturation,
            )
            yield t, wrench, truth

    def _desk(self, k0: int, k1: int, state: np.ndarray | None) -> DeskSamples:
        """The timeline's samples k0 … k1-1 on the desk (``state`` None: at rest under the
        first load)."""
        loads, truth = self.timeline.render(k0, k1)
        loads += self._base
        if self._discrete is None:
            return DeskSamples(loads, truth, self.model.static_readings(loads), None, state)
        if state is None:
            state = self._discrete.initial_state(loads[0])
        motion = None
        if self.accelerometer is not None:
            true, motion, state = self._discrete.run_moving(loads, state)
        else:
            true, state = self._discrete.run(loads, state)
        return DeskSamples(loads, truth, true, motion, state)

    def _cell_chunks(
        self, cells: LoadCellModel
    ) -> Iterator[tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]]:
        """:meth:`chunks` of a desk of load cells: the desk on the fine grid, each reading
        its conversion's average (:mod:`.loadcells`)."""
        points = cells.conversions.points
        n_fine = self.timeline.n_samples
        history: np.ndarray | None = None
        state = creep = None
        for c, k0 in enumerate(range(0, self.n_samples, CHUNK)):
            k1 = min(k0 + CHUNK, self.n_samples)
            a, b = k0 * points, min(k1 * points, n_fine)
            desk = self._desk(a, b, state)
            state = desk.state
            fine = cells.channels(desk.true)
            if history is None:  # the desk stood still under its first load before
                history = np.repeat(fine[:1], cells.conversions.history, axis=0)
            k = np.arange(k0, k1)
            converted = cells.convert(fine, a, history, k)
            history = np.concatenate([history, fine])[-cells.conversions.history :]
            t = k / self.fs
            columns = {name: values[::points] for name, values in desk.truth.items()}
            if self.accelerometer is not None:
                moving = None if desk.motion is None else desk.motion[::points]
                columns.update(self._accelerometer(desk.loads[::points], moving, c))
            readings, creep = cells.apply(
                converted,
                t,
                creep,
                noise_rng=stream(self.seed, STREAM_NOISE, c) if self.effects.noise else None,
                drift=self._drift,
                quantisation=self.effects.quantisation,
                saturation=self.effects.saturation,
            )
            yield t, readings, columns

    def _accelerometer(
        self, loads: np.ndarray, motion: np.ndarray | None, chunk: int
    ) -> dict[str, np.ndarray]:
        """The accelerometer's columns for one chunk (a desk without dynamics stands still)."""
        assert self.accelerometer is not None
        if motion is None:
            qdd = q = np.zeros((len(loads), 6))
        else:
            qdd, q = self.model.accelerations(loads, motion), motion[:, :6]
        readings = self.accelerometer.readings(
            qdd,
            q,
            noise_rng=stream(self.seed, STREAM_ACCEL, chunk) if self.effects.noise else None,
            saturation=self.effects.saturation,
        )
        return {name: readings[:, i] for i, name in enumerate(self.accelerometer.columns)}


def simulate(
    profile: DeskProfile,
    scene: Scene,
    seed: int | None = None,
    noise: bool = True,
    *,
    effects: SimEffects | None = None,
    desk: DeskParameters | None = None,
    sensors: SensorParameters | None = None,
    cells: LoadCellParameters | None = None,
) -> Recording:
    """Simulate ``scene`` on the desk ``profile`` into a recording with ground truth.

    ``seed`` None uses the scene's seed. ``noise=False`` switches off every random sensor
    error (noise, offset and drift); ``effects`` chooses effects one by one. The recording's
    ``extra`` holds the truth per sample: ``true_x, true_y, true_z`` (the contact point, the
    centre of pressure when several fingers touch; NaN when nobody touches), ``true_fn`` (the
    normal force, 0 when not touching), ``true_fx, true_fy, true_fz`` (the force the fingers
    apply, desk frame), ``true_surface`` and ``true_action`` (indices, -1 when not touching);
    then, for a desk with accelerometers, their readings ``acc_x, acc_y, acc_z``, ``acc2_x``, …
    (m/s², the axes the profile lists).

    A desk of six-axis sensors takes ``sensors`` (default: the paper's); a desk of load cells
    (or any other sensors) ``cells`` (default :meth:`LoadCellParameters.for_rate`), and its
    recording holds the raw channels (k, C).
    """
    run = SimulationRun(
        profile, scene, seed, noise=noise, effects=effects, desk=desk, sensors=sensors, cells=cells
    )
    if run.n_samples > MAX_SIMULATE_SAMPLES:
        fs = run.fs
        raise ConfigError(
            scene.where,
            f"the scene lasts {run.timeline.duration_s:g} s, {run.n_samples} samples at "
            f"{fs:g} Hz; a simulated recording holds at most {MAX_SIMULATE_SAMPLES} samples "
            f"({MAX_SIMULATE_SAMPLES / fs:g} s at this desk's rate): shorten the scene (a "
            "`run --source sim:SCENE` streams a longer one)",
        )
    parts = list(run.chunks())
    t = np.concatenate([p[0] for p in parts])
    wrench = np.concatenate([p[1] for p in parts])
    extra = {c: np.concatenate([p[2][c] for p in parts]) for c in run.columns}
    channels = None if profile.six_axis_only else profile.channel_names()
    return Recording(t, wrench, profile.sensor_names, extra, channels)


class SimSource(Source):
    """A simulated desk as a source of wrench blocks (``hapticdesk run --source sim:…``).

    Blocks carry the ground truth in ``WrenchBlock.truth``. The samples equal
    :func:`simulate`'s for the same arguments, whatever ``block_size``.
    """

    def __init__(
        self,
        profile: DeskProfile,
        scene: Scene,
        seed: int | None = None,
        block_size: int = 12,
        *,
        noise: bool = True,
        effects: SimEffects | None = None,
        desk: DeskParameters | None = None,
        sensors: SensorParameters | None = None,
        cells: LoadCellParameters | None = None,
    ) -> None:
        if block_size < 1:
            raise ValueError(f"block_size must be >= 1, found {block_size}")
        self.run = SimulationRun(
            profile,
            scene,
            seed,
            noise=noise,
            effects=effects,
            desk=desk,
            sensors=sensors,
            cells=cells,
        )
        self.block_size = int(block_size)
        super().__init__(
            profile.sensor_names, profile.sample_rate_hz, channel_count=profile.channel_count
        )
        self._chunks = self.run.chunks()
        # the run's samples not yet handed out: [self._at:] of these
        self._t: np.ndarray | None = None
        self._wrench: np.ndarray | None = None
        self._truth: dict[str, np.ndarray] = {}
        self._at = 0

    @property
    def n_samples(self) -> int:
        """How many samples the run has."""
        return self.run.n_samples

    @property
    def duration_s(self) -> float:
        return self.run.timeline.duration_s

    def read_block(self) -> WrenchBlock | None:
        """The next ``block_size`` samples (the last block may be shorter); None at the
        scene's end."""
        while self._left() < self.block_size:
            chunk = next(self._chunks, None)
            if chunk is None:
                break
            self._take(*chunk)
        n = min(self.block_size, self._left())
        if n == 0 or self._t is None or self._wrench is None:
            return None
        a, b = self._at, self._at + n
        self._at = b
        columns = {c: v[a:b] for c, v in self._truth.items()}
        return WrenchBlock(self._t[a:b], self._wrench[a:b], columns, accel_table(columns))

    def _left(self) -> int:
        return 0 if self._t is None else len(self._t) - self._at

    def _take(self, t: np.ndarray, wrench: np.ndarray, truth: dict[str, np.ndarray]) -> None:
        """A chunk of the run after what is left of the last one."""
        if self._t is None or self._wrench is None:
            self._t, self._wrench, self._truth = t, wrench, dict(truth)
        else:
            a = self._at
            self._t = np.concatenate([self._t[a:], t])
            self._wrench = np.concatenate([self._wrench[a:], wrench])
            self._truth = {c: np.concatenate([v[a:], truth[c]]) for c, v in self._truth.items()}
        self._at = 0

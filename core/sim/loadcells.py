"""What load cells and their converters deliver: one reading per raw channel, converted over
a period, with a gain of its own, creep, a zero that drifts, noise, a rounding step and a
limit.

A load cell measures the force along its own axis (``kind: load_cell``: one channel, fz);
the simulated desk stands such a cell's leg on a pin (:mod:`.desk`), so the cells' axial
forces carry the desk's weight and every press. The same model serves any sensor that is
not a six-axis one (a three-axis cell, a plate's calibrated channels): the sensor's wrench in
its own frame becomes its raw channels through the pseudo-inverse of its calibration
(:meth:`SensorSpec.own_wrench_matrix`; for a subset of axes, those axes).

Conversion. A sigma-delta converter (HX711, ADS1256) does not sample a point: each reading
is the input averaged over its conversion (its sinc filter; a box here). The desk is
simulated on a finer grid (:func:`oversampling`, at least 1 kHz and four points per reading)
and each reading averages the fine points of its own conversion:

- ``simultaneous``: every channel over the same period, ending at the reading's time;
- ``multiplexed``: one converter takes the channels in turn within each period (an ADS1256
  behind its multiplexer): channel i over ``T/C``, ending ``(C − 1 − i)·T/C`` before the
  reading's time;
- ``independent``: a converter per channel on its own clock (four HX711s): converter i
  runs ``1 + ε_i`` slower than nominal (ε_i drawn with σ ``clock_tolerance``) from a phase
  of its own, and a reading carries each converter's latest finished conversion, up to one
  period old, sometimes the same one twice or one skipped.

Then, per channel and in this order: its gain (the cell's true sensitivity over the
profile's, ``gains``), creep (a load change creeps on by ``creep`` of itself with time
constant ``creep_time_s``, and back when it is taken off: a first-order response, started
settled under the desk's weight), zero offset and linear drift, white noise per reading,
rounding to the converter's step in newtons (``lsb_n``) and clipping at the channel's range.

The defaults are about an HX711 at 80 Hz reading a 20 kg bar cell; the presets
(:meth:`LoadCellParameters.hx711`, :meth:`~LoadCellParameters.ads1256`) derive noise and step
from the datasheets through the cell's sensitivity, times a margin for a hobby board's supply
and wiring (their docstrings say how).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
import scipy.signal

from hapticdesk.files.profile import DeskProfile
from hapticdesk.sim.sensors import PAPER_RATING

SAMPLINGS = ("simultaneous", "multiplexed", "independent")
#: the finest a converter's conversion is followed: the desk is simulated at least this fast
MIN_FINE_RATE_HZ = 1000.0
MIN_FINE_POINTS = 4  # and with at least this many points per reading
#: a converter's clock is at most this far off (its drawn error is clipped here)
MAX_CLOCK_ERROR = 0.05
#: a moment channel's noise and step per newton of a force channel's (the paper sensor's
#: 4 N·m over 300 N, as the six-axis model scales its channels)
MOMENT_PER_FORCE_M = float(PAPER_RATING[3] / PAPER_RATING[2])

# the sensitivity of the cells the presets assume: a 20 kg (196 N) bar cell rated 1.0 mV/V
CELL_RATED_N = 20 * 9.80665
CELL_MV_PER_V = 1.0
#: a hobby board's noise over the converter's own datasheet figure (supply, wiring, the cell)
BOARD_NOISE_MARGIN = 2.5


def _chain_newtons(volts: float, excitation_v: float) -> float:
    """An input voltage (V) as newtons on the presets' cell excited at ``excitation_v``."""
    return volts / (CELL_MV_PER_V * 1e-3 * excitation_v / CELL_RATED_N)


@dataclass(frozen=True)
class LoadCellParameters:
    """A load cell and its converter (see the module docstring for the order of effects).

    - ``noise_n``: σ of each reading's white noise on a force channel, N, for a cell rated
      ``rated_n``.
    - ``lsb_n``: the converter's step in newtons for such a cell (0: readings are not
      rounded).
    - ``rated_n``: the cell those two are given for. A channel the profile rates otherwise
      (``range: {force_n: ...}``) gets them scaled by its rating: the converter's volts are
      more newtons on a bigger cell of the same mV/V.
    - ``creep``, ``creep_time_s``: the share of a load change the reading creeps on by, and
      how fast (a datasheet's "creep in 30 min", 0.02–0.1 % of the load for cheap cells).
    - ``gains``: each raw channel's true gain over what the profile assumes (empty: all 1);
      "one cell's gain a few percent off" is ``(1.03, 1, 1, 1)``.
    - ``offset_n``, ``drift_n_per_min``: σ of each channel's zero offset and drift rate.
    - ``sampling``: ``simultaneous``, ``multiplexed`` or ``independent`` (module docstring).
    - ``clock_tolerance``: σ of each converter's clock error, ``independent`` only.
    """

    noise_n: float = 0.01
    lsb_n: float = 1e-4
    rated_n: float = CELL_RATED_N
    creep: float = 0.0005
    creep_time_s: float = 300.0
    gains: tuple[float, ...] = field(default_factory=tuple)
    offset_n: float = 2.0
    drift_n_per_min: float = 0.02
    sampling: str = "simultaneous"
    clock_tolerance: float = 0.01

    def __post_init__(self) -> None:
        if self.sampling not in SAMPLINGS:
            raise ValueError(
                f"sampling must be one of {', '.join(SAMPLINGS)}, found {self.sampling!r}"
            )
        values = {
            "noise_n": self.noise_n,
            "lsb_n": self.lsb_n,
            "creep": self.creep,
            "offset_n": self.offset_n,
            "drift_n_per_min": self.drift_n_per_min,
            "clock_tolerance": self.clock_tolerance,
        }
        for name, value in values.items():
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be a number >= 0, found {value}")
        for name in ("creep_time_s", "rated_n"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be positive, found {value}")
        if not all(math.isfinite(g) and g > 0 for g in self.gains):
            raise ValueError(f"gains must be positive numbers, found {self.gains}")

    @classmethod
    def hx711(cls, rate_hz: float = 80.0, **changes: object) -> LoadCellParameters:
        """An HX711 per cell, each on its own on-chip oscillator (``sampling`` stays
        ``simultaneous`` unless given: four chips converting in step is the best case).

        Datasheet: input noise 90 nV rms at 80 SPS, 50 nV at 10 SPS (gain 128); full scale
        ±0.5·AVDD/128 over 24 bits. A module's regulator gives AVDD = 4.3 V, the cell's
        excitation too: 1 mV/V × 4.3 V over 196 N is 21.9 µV/N, so 90 nV is 0.0041 N, times
        :data:`BOARD_NOISE_MARGIN`; one step (2.0 nV) is 9e-5 N.
        """
        avdd = 4.3
        noise_v = 90e-9 if rate_hz > 10.0 else 50e-9
        step_v = 2 * (0.5 * avdd / 128) / 2**24
        preset = cls(
            noise_n=BOARD_NOISE_MARGIN * _chain_newtons(noise_v, avdd),
            lsb_n=_chain_newtons(step_v, avdd),
        )
        return _with(preset, changes)

    @classmethod
    def ads1256(cls, **changes: object) -> LoadCellParameters:
        """One ADS1256 taking four bridges in turn at 1 kHz each (``multiplexed``).

        Datasheet (2.5 V reference, PGA 64, 1 kSPS class): about 0.2 µV rms input noise;
        full scale ±2·2.5 V/64 over 24 bits. A 5 V excitation gives 25.5 µV/N on the
        presets' cell: 0.2 µV is 0.0078 N, times :data:`BOARD_NOISE_MARGIN`; one step
        (9.3 nV) is 3.7e-4 N.
        """
        excitation = 5.0
        step_v = 2 * (2 * 2.5 / 64) / 2**24
        preset = cls(
            noise_n=BOARD_NOISE_MARGIN * _chain_newtons(0.2e-6, excitation),
            lsb_n=_chain_newtons(step_v, excitation),
            sampling="multiplexed",
        )
        return _with(preset, changes)

    @classmethod
    def for_rate(cls, rate_hz: float, **changes: object) -> LoadCellParameters:
        """The converter a desk sampled at ``rate_hz`` would have: HX711s up to 80 Hz, an
        ADS1256 above."""
        if rate_hz <= 80.0 + 1e-9:
            return cls.hx711(rate_hz, **changes)
        return cls.ads1256(**changes)


def with_total_amplitude(
    profile: DeskProfile, amplitude_n: float, params: LoadCellParameters | None = None
) -> LoadCellParameters:
    """``params`` (default: the rate's converter) with the noise that makes 3σ of the desk's
    total F_z at rest ``amplitude_n`` (the six-axis sensors' measure, SensorParameters's
    ``noise_amplitude_n``), each cell's share scaled by its rating as usual."""
    if not (math.isfinite(amplitude_n) and amplitude_n >= 0):
        raise ValueError(f"the noise amplitude must be a number >= 0, found {amplitude_n}")
    params = params or LoadCellParameters.for_rate(profile.sample_rate_hz)
    unit = replace(params, noise_n=1.0)
    zero = np.zeros(profile.channel_count)
    sigma = LoadCellModel(profile, unit, Conversions(1, zero, zero, zero, zero, False)).noise_sigma
    per_unit = float(np.sqrt(np.sum((profile.wrench_map()[2] * sigma) ** 2)))
    return replace(params, noise_n=amplitude_n / 3.0 / per_unit)


def _with(preset: LoadCellParameters, changes: dict[str, object]) -> LoadCellParameters:
    return replace(preset, **changes) if changes else preset  # type: ignore[arg-type]


def oversampling(rate_hz: float, channels: int, sampling: str) -> int:
    """Fine points per reading: the desk is simulated at ``rate_hz`` times this, at least
    :data:`MIN_FINE_RATE_HZ` and :data:`MIN_FINE_POINTS` per reading (and one point per
    channel for ``multiplexed``)."""
    n = max(MIN_FINE_POINTS, math.ceil(MIN_FINE_RATE_HZ / rate_hz - 1e-9))
    if sampling == "multiplexed":
        n = max(n, channels)
    return n


@dataclass(frozen=True)
class Conversions:
    """When each channel's readings are converted, on the fine grid of ``points`` per
    reading: reading k of channel i averages the fine points ``(end − length_i, end]`` with
    ``end`` = :meth:`ends` ``(k)[:, i]``."""

    points: int  # fine points per reading
    lengths: np.ndarray  # (C,) fine points each conversion averages
    lag: np.ndarray  # (C,) multiplexed: fine points channel i ends before the reading
    period: np.ndarray  # (C,) independent: each converter's period in fine points
    phase: np.ndarray  # (C,) ... and the fine time of its conversion 0
    independent: bool

    @classmethod
    def of(
        cls,
        sampling: str,
        channels: int,
        points: int,
        clock_tolerance: float,
        rng: np.random.Generator,
    ) -> Conversions:
        """The conversions of ``channels`` channels; ``rng`` draws independent clocks."""
        zero = np.zeros(channels)
        if sampling == "simultaneous":
            return cls(points, np.full(channels, points), zero.astype(int), zero, zero, False)
        if sampling == "multiplexed":
            share = max(1, points // channels)
            lag = (channels - 1 - np.arange(channels)) * share
            return cls(points, np.full(channels, share), lag, zero, zero, False)
        error = np.clip(
            rng.standard_normal(channels) * clock_tolerance, -MAX_CLOCK_ERROR, MAX_CLOCK_ERROR
        )
        period = points * (1.0 + error)
        phase = rng.uniform(0.0, 1.0, channels) * period
        lengths = np.maximum(1, np.round(period)).astype(int)
        return cls(points, lengths, zero.astype(int), period, phase, True)

    @property
    def history(self) -> int:
        """Fine points before a reading's own that its conversions may reach back to."""
        return int(self.lengths.max() + self.lag.max() + np.ceil(self.period.max()) + 2)

    def ends(self, k: np.ndarray) -> np.ndarray:
        """(len(k), C) the fine index each channel's conversion for reading ``k`` ends at."""
        now = np.asarray(k, dtype=np.int64)[:, None] * self.points
        if not self.independent:
            return now - self.lag[None, :]
        n = np.floor((now - self.phase[None, :]) / self.period[None, :] + 1e-9)
        return np.floor(self.phase[None, :] + n * self.period[None, :] + 1e-9).astype(np.int64)

    def times(self, k: np.ndarray, rate_hz: float) -> np.ndarray:
        """(len(k), C) the time each channel's reading ``k`` stands for, seconds: the middle
        of its conversion (what a board that stamps each conversion would send)."""
        middle = self.ends(k) - (self.lengths[None, :] - 1) / 2.0
        return middle / (rate_hz * self.points)


class LoadCellModel:
    """Turns a desk's sensor wrenches on the fine grid into raw channel readings (module
    docstring). It holds no state: the simulator hands it the last fine points and the
    creep's state from chunk to chunk, so any split gives the same readings."""

    def __init__(
        self,
        profile: DeskProfile,
        params: LoadCellParameters,
        conversions: Conversions,
    ) -> None:
        self.params = p = params
        self.conversions = conversions
        self.rate_hz = float(profile.sample_rate_hz)
        # (S, 6) -> (C,): each sensor's own wrench to its raw channels
        blocks = [np.linalg.pinv(s.own_wrench_matrix()) for s in profile.sensors]
        self.n_sensors = len(profile.sensors)
        self.to_channels = _block_diag(blocks)  # (C, 6S)
        c = profile.channel_count
        if p.gains and len(p.gains) != c:
            raise ValueError(
                f"gains must give one number per raw channel ({c} for desk {profile.name!r}: "
                f"{', '.join(profile.channel_names())}), found {len(p.gains)}"
            )
        self.gains = np.array(p.gains, dtype=float) if p.gains else np.ones(c)
        # each channel's units per newton (a load cell's fz: 1), moment channels per N·m·
        unit = np.concatenate([_channel_units(s.own_wrench_matrix()) for s in profile.sensors])
        limits = profile.channel_limits()
        self.limits = np.full(c, np.inf) if limits is None else limits
        # the same volts are more newtons on a cell rated higher (in the channel's units)
        rated = np.where(np.isfinite(self.limits), self.limits / unit, p.rated_n) / p.rated_n
        self.noise_sigma = p.noise_n * unit * rated
        self.step = p.lsb_n * unit * rated
        self.offset_sigma = p.offset_n * unit * rated
        self.drift_sigma = p.drift_n_per_min / 60.0 * unit * rated

    def channels(self, readings: np.ndarray) -> np.ndarray:
        """Sensor wrenches (k, S, 6), each in its own frame, as raw channels (k, C)."""
        flat = readings.reshape(len(readings), 6 * self.n_sensors)
        return flat @ self.to_channels.T

    def draw_drift(self, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """Per-channel zero offsets and drift rates (C,) each."""
        offset = rng.standard_normal(len(self.gains)) * self.offset_sigma
        rate = rng.standard_normal(len(self.gains)) * self.drift_sigma
        return offset, rate

    def convert(
        self, fine: np.ndarray, first_fine: int, history: np.ndarray, k: np.ndarray
    ) -> np.ndarray:
        """Readings (len(k), C) of the fine channel values ``fine`` (m, C) from fine index
        ``first_fine`` on, ``history`` (H, C) the :attr:`Conversions.history` points before
        them; ``k`` the readings' indices."""
        joined = np.concatenate([history, fine])
        base = first_fine - len(history)  # fine index of joined[0]
        ref = joined[0]
        total = np.vstack([np.zeros((1, joined.shape[1])), np.cumsum(joined - ref, axis=0)])
        ends = self.conversions.ends(k) - base + 1  # rows after each conversion's last point
        starts = ends - self.conversions.lengths[None, :]
        if starts.min() < 0 or ends.max() > len(joined):
            raise RuntimeError("a conversion reaches beyond the points at hand")  # (a bug)
        cols = np.arange(joined.shape[1])[None, :]
        return (total[ends, cols] - total[starts, cols]) / self.conversions.lengths + ref

    def apply(
        self,
        converted: np.ndarray,
        t: np.ndarray,
        creep_state: np.ndarray | None,
        *,
        noise_rng: np.random.Generator | None,
        drift: tuple[np.ndarray, np.ndarray] | None,
        quantisation: bool,
        saturation: bool,
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """Gain, creep (with ``drift``), offset and drift, noise, rounding and clipping of
        converted readings (k, C) at times ``t``; returns them and the creep state to carry
        (``creep_state`` None: settled under the first reading)."""
        out = converted * self.gains
        if drift is not None and self.params.creep > 0 and len(out):
            out, creep_state = self._creep(out, creep_state)
        if drift is not None:
            offset, rate = drift
            out = out + offset + rate * t[:, None]
        if noise_rng is not None:
            out = out + noise_rng.standard_normal(out.shape) * self.noise_sigma
        if quantisation:
            has_step = self.step > 0
            step = np.where(has_step, self.step, 1.0)
            out = np.where(has_step, np.round(out / step) * step, out)
        if saturation:
            out = np.clip(out, -self.limits, self.limits)
        return out, creep_state

    def _creep(self, values: np.ndarray, state: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
        """``values + creep · L(values)``: L a first-order low-pass of unit gain and time
        constant ``creep_time_s`` (a step creeps on as 1 − e^(−t/τ))."""
        pole = math.exp(-1.0 / (self.rate_hz * self.params.creep_time_s))
        b, a = np.array([1.0 - pole]), np.array([1.0, -pole])
        if state is None:  # settled under the first reading (the desk has stood for long)
            state = values[0] * pole
        settled, final = scipy.signal.lfilter(b, a, values, axis=0, zi=state[None, :])
        return values + self.params.creep * settled, final[0]


def _channel_units(own: np.ndarray) -> np.ndarray:
    """(n,) each raw channel's units per newton of a force it measures (per N·m of a
    moment, scaled by :data:`MOMENT_PER_FORCE_M`, for a channel that measures only moments)."""
    force = np.linalg.norm(own[:3], axis=0)
    moment = np.linalg.norm(own[3:], axis=0)
    per_force = np.where(force > 0, 1.0 / np.where(force > 0, force, 1.0), 0.0)
    per_moment = MOMENT_PER_FORCE_M / np.where(moment > 0, moment, 1.0)
    return np.where(force > 0, per_force, per_moment)


def _block_diag(blocks: list[np.ndarray]) -> np.ndarray:
    """(Σ rows, 6·len) with each (n_i, 6) block on the diagonal."""
    rows = sum(b.shape[0] for b in blocks)
    out = np.zeros((rows, 6 * len(blocks)))
    r = 0
    for i, b in enumerate(blocks):
        out[r : r + b.shape[0], 6 * i : 6 * i + 6] = b
        r += b.shape[0]
    return out

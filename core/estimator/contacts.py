"""Contact samples (one per input sample, struct of arrays) and contact events (down, move, up).

This is what the estimator gives and what the gesture recognizers consume (the docs' contracts:
gestures see contacts only). Arrays never hold NaN or infinity: where a contact is not located,
``located`` is False and x, y, z hold 0.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Literal

import numpy as np

# source codes
SOURCE_NONE, SOURCE_FORCE, SOURCE_DIFF, SOURCE_FUSED = 0, 1, 2, 3
SOURCE_NAMES = ("", "force", "diff", "fused")
# phase codes
PHASE_NONE, PHASE_TOUCH, PHASE_HOLD, PHASE_RELEASE = 0, 1, 2, 3
PHASE_NAMES = ("", "touch", "hold", "release")
# bad-sample flags (bits)
FLAG_NAN = 1  # NaN or infinity in a channel or the time
FLAG_SATURATED = 2  # a channel at or beyond the sensor's rated range
FLAG_TIME_BACK = 4  # time did not increase
FLAG_GAP = 8  # the time jumped by more than max_gap_s before this sample; filters restarted
FLAG_NOT_TARED = 16  # no zero yet (tare pending or refused)
FLAG_STUCK = 32  # every channel bit-identical to the sample before, for a run: a stuck driver
FLAG_MULTI = 64  # a second finger on the desk (hapticdesk.estimator.multitouch)
#: the change of wrench that shows a second finger's landing is taken over this long, so
#: the samples up to this long before the flag may already mix both fingers
MULTI_LAG_S = 0.08
# the desk has an accelerometer but this sample's reading is missing or saturated: its
# inertial force is not removed (hapticdesk.estimator.inertia)
FLAG_NO_ACCEL = 128
#: the flags of a sample the estimator skips: it holds the last good sample's wrench instead
BAD_SAMPLE = FLAG_NAN | FLAG_SATURATED | FLAG_TIME_BACK | FLAG_STUCK
FLAG_NAMES = {
    FLAG_NAN: "nan",
    FLAG_SATURATED: "saturated",
    FLAG_TIME_BACK: "time_back",
    FLAG_GAP: "gap",
    FLAG_NOT_TARED: "not_tared",
    FLAG_STUCK: "stuck",
    FLAG_MULTI: "multi",
    FLAG_NO_ACCEL: "no_accel",
}
UNCERTAINTY_CAP_M = 10.0  # stands for "unknown" so the arrays stay finite
SHEAR_CAP = 100.0  # the largest ContactBlock.shear: a force along the surface, none into it


def _left_out() -> np.ndarray:
    """A field's default when a caller builds a block without it (filled to length k)."""
    return np.zeros(0)


@dataclass
class ContactBlock:
    """Estimator output for k input samples.

    A block that :meth:`ContactEstimator.push <hapticdesk.estimator.ContactEstimator.push>`
    returns is a view of the estimator's own output columns: it holds until the next push to
    the same estimator, which writes over it. Use it (feed it on, read it) before the next
    push; keep it with :meth:`copy`.
    """

    t: np.ndarray  # (k,) float64
    in_contact: np.ndarray  # (k,) bool: the fast path says a finger is on the desk
    located: np.ndarray  # (k,) bool: a contact point was found on a surface
    surface: np.ndarray  # (k,) int16 index into the profile's surfaces, -1 if not located
    x: np.ndarray  # (k,) desk frame, metres
    y: np.ndarray
    z: np.ndarray
    force_n: np.ndarray  # (k,) |F| of the external force (fast path), newtons
    source: np.ndarray  # (k,) int8 SOURCE_*
    phase: np.ndarray  # (k,) int8 PHASE_*
    sigma_m: np.ndarray  # (k,) 1-σ radial uncertainty of (x, y, z), metres
    flags: np.ndarray  # (k,) uint8 FLAG_* bits
    # the second finger of a FLAG_MULTI contact, once its place is fitted (multitouch); the
    # fields were added later, so they may be left out: not located, zeros
    located2: np.ndarray = field(default_factory=_left_out)  # (k,) bool
    x2: np.ndarray = field(default_factory=_left_out)  # (k,) desk frame, m; 0 if not located2
    y2: np.ndarray = field(default_factory=_left_out)
    z2: np.ndarray = field(default_factory=_left_out)
    # (k,) bool: in contact, and the load has been as still as an object put down since the
    # last window judged (the zero stage's verdict is pending); added later, may be left out
    resting: np.ndarray = field(default_factory=_left_out)
    # (k,) float: at a located sample, the external force's share along the surface over its
    # share into it (|F_t| / |F_n|, at most SHEAR_CAP): a finger sliding drags the surface
    # (0.3 and more, friction), a tap presses into it; 0 elsewhere. Added later, may be left out
    shear: np.ndarray = field(default_factory=_left_out)
    # (k,) the finger's drag along a horizontal board at a located sample, desk x and y in
    # newtons (the force along the surface, the finger's way: the way it slides); 0 elsewhere
    # and on other surfaces. Added later, may be left out
    drag_x: np.ndarray = field(default_factory=_left_out)
    drag_y: np.ndarray = field(default_factory=_left_out)

    def __post_init__(self) -> None:
        k = len(self.t)
        for name in ("located2", "resting"):
            value = getattr(self, name)
            if len(value) != k:
                setattr(self, name, np.zeros(k, bool))
            elif value.dtype != np.bool_:  # (k = 0: the default's float zeros)
                setattr(self, name, value.astype(bool))
        for name in ("x2", "y2", "z2", "shear", "drag_x", "drag_y"):
            if len(getattr(self, name)) != k:
                setattr(self, name, np.zeros(k))

    def __len__(self) -> int:
        return len(self.t)

    @classmethod
    def concat(cls, blocks: list[ContactBlock]) -> ContactBlock:
        """Join blocks in order."""
        if not blocks:
            return cls.empty()
        return cls(
            **{f.name: np.concatenate([getattr(b, f.name) for b in blocks]) for f in fields(cls)}
        )

    @classmethod
    def empty(cls) -> ContactBlock:
        z = np.zeros(0)
        return cls(
            z,
            z.astype(bool),
            z.astype(bool),
            z.astype(np.int16),
            z,
            z.copy(),
            z.copy(),
            z.copy(),
            z.astype(np.int8),
            z.astype(np.int8),
            z.copy(),
            z.astype(np.uint8),
            z.astype(bool),
            z.copy(),
            z.copy(),
            z.copy(),
            z.astype(bool),
            z.copy(),
            z.copy(),
            z.copy(),
        )

    @classmethod
    def blank(cls, t: np.ndarray) -> ContactBlock:
        """A block for the samples at times ``t``: not in contact, nothing located."""
        k = len(t)
        return cls(
            t=np.array(t, dtype=float),
            in_contact=np.zeros(k, bool),
            located=np.zeros(k, bool),
            surface=np.full(k, -1, np.int16),
            x=np.zeros(k),
            y=np.zeros(k),
            z=np.zeros(k),
            force_n=np.zeros(k),
            source=np.zeros(k, np.int8),
            phase=np.zeros(k, np.int8),
            sigma_m=np.full(k, UNCERTAINTY_CAP_M),
            flags=np.zeros(k, np.uint8),
            located2=np.zeros(k, bool),
            x2=np.zeros(k),
            y2=np.zeros(k),
            z2=np.zeros(k),
            resting=np.zeros(k, bool),
            shear=np.zeros(k),
            drag_x=np.zeros(k),
            drag_y=np.zeros(k),
        )

    def copy(self) -> ContactBlock:
        """The block with arrays of its own (an estimator's block holds until its next push)."""
        return ContactBlock(**{f.name: getattr(self, f.name).copy() for f in fields(self)})

    def take(self, index: np.ndarray | slice) -> ContactBlock:
        """A sub-block (boolean mask, index array or slice; a slice gives views, so writing
        into the sub-block writes into this one)."""
        return ContactBlock(**{f.name: getattr(self, f.name)[index] for f in fields(self)})


@dataclass(frozen=True)
class ContactEvent:
    """One contact event on sample time: ``down`` starts a touch, ``move`` updates, ``up`` ends.

    ``located`` False means the position is not known at this sample (x, y hold the last
    located values of this touch, or 0). ``sigma_m`` is the 1-σ uncertainty of the position.
    ``multi``: a second finger is on the desk (``FLAG_MULTI``): x, y are then the two fingers'
    centre of pressure, not a finger; ``x2``, ``y2`` where the second finger is, once
    ``located2``. ``resting``: the load is as still as an object put down, and the estimator
    has not yet decided whether it is one (``ContactBlock.resting``).
    """

    t: float
    kind: Literal["down", "move", "up"]
    x: float
    y: float
    surface: int
    force_n: float
    sigma_m: float
    phase: str
    located: bool
    multi: bool = False
    located2: bool = False
    x2: float = 0.0
    y2: float = 0.0
    resting: bool = False
    shear: float = 0.0  # ContactBlock.shear: tangential over normal force (0: not located)
    drag_x: float = 0.0  # ContactBlock.drag_x, drag_y: the finger's drag on a horizontal board
    drag_y: float = 0.0


def contact_events(block: ContactBlock, was_in_contact: bool = False) -> list[ContactEvent]:
    """Turn a block into events. ``was_in_contact``: the state before the block's first sample.

    Every contact sample gives one event; the first of a touch is ``down``; the sample after
    the last (the first sample out of contact) gives ``up`` with the last located position.
    """
    events: list[ContactEvent] = []
    prev = was_in_contact
    last_xy = (0.0, 0.0, -1)
    # plain Python over the block: events are consumed one by one by state machines anyway
    t = block.t.tolist()
    inc = block.in_contact.tolist()
    loc = block.located.tolist()
    xs, ys = block.x.tolist(), block.y.tolist()
    surf = block.surface.tolist()
    force = block.force_n.tolist()
    sig = block.sigma_m.tolist()
    phase = block.phase.tolist()
    multi = ((block.flags & FLAG_MULTI) != 0).tolist()
    loc2, xs2, ys2 = block.located2.tolist(), block.x2.tolist(), block.y2.tolist()
    resting = block.resting.tolist()
    shear = block.shear.tolist()
    drag_x, drag_y = block.drag_x.tolist(), block.drag_y.tolist()
    for i in range(len(t)):
        if loc[i]:
            last_xy = (xs[i], ys[i], surf[i])
        if inc[i]:
            kind: Literal["down", "move", "up"] = "move" if prev else "down"
            events.append(
                ContactEvent(
                    t[i],
                    kind,
                    last_xy[0],
                    last_xy[1],
                    last_xy[2],
                    force[i],
                    sig[i] if loc[i] else UNCERTAINTY_CAP_M,
                    PHASE_NAMES[phase[i]],
                    bool(loc[i]),
                    multi[i],
                    loc2[i],
                    xs2[i],
                    ys2[i],
                    resting[i],
                    shear[i] if loc[i] else 0.0,
                    drag_x[i] if loc[i] else 0.0,
                    drag_y[i] if loc[i] else 0.0,
                )
            )
        elif prev:
            events.append(_lift_off(t[i], last_xy, force[i], sig[i]))
        prev = inc[i]
    return events


def _lift_off(
    t: float, last_xy: tuple[float, float, int], force: float, sigma: float
) -> ContactEvent:
    """The ``up`` event of the first sample out of contact, at the touch's last located
    position (x, y, surface)."""
    x, y, surface = last_xy
    return ContactEvent(t, "up", x, y, surface, force, sigma, "release", False)

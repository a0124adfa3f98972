"""Stage 1, bad samples and gaps: the raw channels in, flags and the resultant wrench out.

NaN or infinity, a saturated channel, a time that does not increase and a stuck input flag a
sample, and the last good wrench is held over it, so no filter state is poisoned; a time step
between good samples longer than ``max_gap_s`` flags a gap (the filters restart there). Good
samples become the resultant wrench [F_o; M_o] about P_o by one general channels→wrench
matrix (6, C) (paper eqs. 1–4; :meth:`DeskProfile.wrench_map`: C = 6·S for six-axis sensors),
and each channel's limit (C,) says where it saturates.

A stuck input is a driver that repeats its last sample: every channel bit-identical to the
sample before, from the ``STUCK_RUN``-th repeat in a row on, with a notice when it sticks and
when it has been live again for ``LIVE_AGAIN_S``. A noisy sensor hardly ever repeats all its
channels exactly (the simulator with the paper's noise, below one step of resolution on
most channels: twice in 105,617 samples, never twice in a row), but a noise-free one does all
the time (the simulator's ideal mode, a sensor quieter than its resolution): the check is on
only for an input with fewer than ``NOISE_FREE_REPEATS`` exact repeats in its first
``NOISE_CHECK_S``. A time that is not after an earlier sample's is told at the 1st, 10th,
100th… such sample.

A reading that jumps from a calm wrench for a sample or a few (a corrupt word from a
converter, a bit error on a line) is held over: the last good sample stands for it while it
stays away, up to ``settings.JUMP_HOLD_S``, and the next is taken whatever it is (a real
change lasts, and lands that late); one that came back is told at the 1st, 10th, 100th…
(``kernel_channels.held_over``; the size of a jump held: ``settings.JUMP_SHARE``).

The per-sample work is ``_samples`` in :mod:`hapticdesk.estimator.kernel_channels`; here are its
constants and the notices it raises (:func:`tell_events`).
"""

from __future__ import annotations

import logging

import numpy as np

from hapticdesk.estimator.kernel_slots import (
    EV_GAP,
    EV_JUMP,
    EV_LIVE,
    EV_NOISE_FREE,
    EV_STUCK,
    EV_TIME_BACK,
    J_JUMP_HELD_N,
    J_JUMPS,
    J_TIME_BACK,
    S_EV_LATEST,
    S_EV_T,
    S_JUMP_SIZE,
    S_JUMP_T,
    S_LAST_STUCK_T,
    S_STUCK_SINCE,
)
from hapticdesk.estimator.notices import Notice, add_notice, log

STUCK_RUN = 5  # this many repeats of a sample in a row (and more) are a stuck input
NOISE_CHECK_S = 0.2  # an input with NOISE_FREE_REPEATS exact repeats this early is noise-free
NOISE_FREE_REPEATS = 3  # ... and has no stuck check
LIVE_AGAIN_S = 1.0  # a stuck input is live again after this long unstuck (bounds the notices)


def tell_time_back(notices: list[Notice], t: float, latest: float, count: int) -> None:
    """The ``count``-th sample (1, 10, 100…) at ``t`` not after ``latest``: a recording whose
    time runs backwards or stands still had ended with no contact and only "tare refused" to
    say why; a log with the odd repeated time stamp says it a few times, not at every one."""
    add_notice(
        notices,
        latest,
        "time_back",
        f"time went back: a sample at t = {t:.6g} s is not after t = {latest:.6g} s ({count} "
        "such so far); they are flagged and skipped (samples out of order, or a clock that "
        "was reset?)",
        logging.WARNING,
    )


def tell_jump(notices: list[Notice], t: float, size: float, count: int, samples: int) -> None:
    """The ``count``-th reading (1, 10, 100…), at ``t``, that jumped by ``size`` newtons for
    ``samples`` samples and came back: held over, so it made no touch."""
    lasted = "one sample" if samples == 1 else f"{samples} samples"
    add_notice(
        notices,
        t,
        "jump",
        f"a reading jumped by {size:.3g} N for {lasted} and came back ({count} such so far):"
        " taken as corrupt and held over (a loose wire, a converter's odd bad word?)",
        logging.WARNING,
    )


def tell_stuck(notices: list[Notice], t: float) -> None:
    """The input sticks at ``t``."""
    add_notice(
        notices,
        t,
        "stuck",
        f"the input is stuck: every channel repeated one sample {STUCK_RUN} times; "
        "its samples are flagged and skipped until it changes (a hung driver?)",
        logging.WARNING,
    )


def tell_live(notices: list[Notice], t: float, since: float, until: float) -> None:
    """The input, stuck from ``since`` to ``until``, has been live again up to ``t``."""
    add_notice(
        notices,
        t,
        "live",
        f"the input is live again: it was stuck from t = {since:.3f} s to {until:.3f} s",
    )


def tell_noise_free() -> None:
    """The input repeats samples exactly: it gets no stuck check (a log line, no notice)."""
    log.info("the input repeats samples exactly (noise-free): no stuck-input check")


def tell_events(notices: list[Notice], events: int, sf: np.ndarray, si: np.ndarray) -> None:
    """The notices of the input's events one sample raised (``kernel_slots.EV_*``: time
    back, noise-free, stuck, live again, a gap), from the kernel's state ``sf``, ``si``."""
    if events & EV_TIME_BACK:
        tell_time_back(notices, float(sf[S_EV_T]), float(sf[S_EV_LATEST]), int(si[J_TIME_BACK]))
    if events & EV_NOISE_FREE:
        tell_noise_free()
    if events & EV_STUCK:
        tell_stuck(notices, float(sf[S_STUCK_SINCE]))
    if events & EV_LIVE:
        tell_live(notices, float(sf[S_EV_T]), float(sf[S_STUCK_SINCE]), float(sf[S_LAST_STUCK_T]))
    if events & EV_JUMP:
        held = int(si[J_JUMP_HELD_N])
        tell_jump(notices, float(sf[S_JUMP_T]), float(sf[S_JUMP_SIZE]), int(si[J_JUMPS]), held)
    if events & EV_GAP:
        add_notice(
            notices,
            float(sf[S_EV_T]),
            "gap",
            "gap in sample times: filters restarted",
            logging.WARNING,
        )

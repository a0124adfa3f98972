"""The compiled estimator's fixed layout: the slots of its flat arrays and its codes.

The kernel (:mod:`hapticdesk.estimator.kernel` and the ``kernel_*`` stage modules) works on
flat arrays only; these names say what sits where: ``P_*``/``I_*`` the parameters' fixed
slots (``pf``, ``pi``; ``I_PO_*``, ``I_IO_*``, ``I_SO_*``, ``I_JO_*`` the offsets of the
desk-sized parts), ``S_*``/``J_*`` the state's (``sf``, ``si``), ``OUT_*`` the output rows,
``TRACE_*`` the trace rows, ``SURF_*``/``COV_*``/``MT_*`` the layout of a surface, its
covariances and the second finger's history, ``EV_*`` the event bits an entry returns and
``RESUME_*`` where it resumes after one. :mod:`hapticdesk.estimator.params` lays the arrays
out by these names, the estimator reads them by these names.

numba freezes these integers into the compiled code: a change here must reach every cached
kernel (:mod:`.kernel_compile` stamps the caches with all ``kernel*.py`` files).
"""

from __future__ import annotations

# --- methods -----------------------------------------------------------------------------------
METHOD_FORCE, METHOD_DIFF, METHOD_SWITCHED, METHOD_FUSED = range(4)  # (profile.METHODS' order)

# --- events (bits of an entry's return value) ---------------------------------------------------
EV_WINDOW = 1  # a zero window ended with this sample (S_WIN_*): judge it
EV_TIME_BACK = 2  # the 1st, 10th, 100th… sample whose time is not after an earlier one's
EV_STUCK = 4  # the input sticks from this sample on
EV_LIVE = 8  # the input has been live again for LIVE_AGAIN_S
EV_GAP = 16  # a gap in the times before this sample: the filters restarted
EV_NOISE_FREE = 32  # the input repeats samples exactly: no stuck check
EV_CONTACT_END = 64  # a contact ended that the second-finger stage learns from
EV_FIT = 128  # the second finger's landing window is full: fit its place
EV_COVS = 256  # a resolution step is new or shrank: make the covariances anew (mid-sample)
EV_PARTIAL_ACCEL = 512  # some readings of several accelerometers are not usable (pre-sample)
EV_ABSORBED = 1024  # a still load joined the zero (S_OBJ_*, J_OBJ_HELD): tell it
EV_LIFTED = 2048  # the last absorbed object was lifted, its zero restored: tell it
EV_JUMP = 4096  # the 1st, 10th, 100th… reading that jumped for one sample and came back
# where an entry resumes after an event (si[J_RESUME])
RESUME_NEXT, RESUME_BACK, RESUME_AGAIN = 0, 1, 2

# --- parameters: fixed float slots (pf) ---------------------------------------------------------
(
    P_MAX_GAP,
    P_CONTACT,
    P_HYSTERESIS,
    P_RELEASE_SLOPE,
    P_DET_DELAY,
    P_PHASE_RATE,
    P_MIN_COS,
    P_MAX_SIGMA,
    P_SPEED,
    P_TOUCH_THRESHOLD,
    P_RELEASE_THRESHOLD,
    P_DIFF_SCALE,
    P_RATE_SCALE,
    P_RELEASE_SCALE,
    P_RING_DECAY,
    P_SWAY_SCALE,
    P_DIFF_INFO_RATIO,
    P_VAR_CAP,
    P_DET_FLOOR,
    P_EDGE_TOLERANCE,
    P_SHEAR_CAP,
    P_SHEAR_CAP_INV,  # 1 / P_SHEAR_CAP (a division a located sample does not make)
    P_UNCERTAINTY_CAP,
    P_STEP_CHANGE,
    P_MT_MIN_STEP,
    P_MT_MIN_STEP_SHARE,
    P_MT_MIN_NORMAL_SHARE,
    P_MT_MAX_FIRST_MOVE,
    P_STILL_N,  # a window whose low-passed force spreads this much is not still
    P_DRIFT_MAX,  # a still load lighter than this is the idle desk's drift
    # the object rule's constants (still_objects.py) and the yardsticks' quantile
    P_OBJECT_STILL_FACTOR,
    P_OBJECT_WANDER_FACTOR,
    P_HEAVY_WANDER_SHARE,
    P_HEAVY_SPREAD_SHARE,
    P_OBJECT_SPIKE,
    P_OBJECT_RESTING_KEEP,
    P_LIGHT_LOAD,
    P_OBJECT_NOISE_FLOOR,
    P_STEP_SPREAD_SHARE,  # a desk quieter than its steps: its yardsticks in steps
    P_STEP_WANDER_SHARE,
    P_LIFT_TOLERANCE,
    P_IDLE_QUANTILE,
    P_JUMP_SQ,  # a change of the wrench's force beyond this, squared, in one sample: a jump
    P_JUMP_ARM_INV_SQ,  # ... or of its moment beyond it times the desk's arm: 1 / arm²
    P_STILL_NOISE_FACTOR,  # ... or this many times the idle desk's quiet spread (yardsticks.py)
    P_NOISY_WANDER_SHARE,  # still_objects.NOISY_WANDER_SHARE
    P_NOISY_STILL_SHARE,  # still_objects.NOISY_STILL_SHARE
    N_PF_FIXED,
) = range(48)
# --- parameters: fixed int slots (pi) -----------------------------------------------------------
(
    I_C,  # raw channels
    I_A,  # accelerometer axes (0: none)
    I_MULTI_ACCEL,  # several accelerometers (partial readings are usable)
    I_N_SURF,
    I_N_UP,  # upright surfaces (ring guard)
    I_METHOD,
    I_DET_FULL,  # the fast filter's moments are used (fused, trace)
    I_SHARED_LP,
    I_TRACE,
    I_NS,  # second-order sections per filter
    I_N_DIFF,
    I_N_RATE,
    I_N_RELEASE,
    I_SPAN,  # the sway's half-width in samples; 0: off
    I_WINDOW,
    I_STILL_BLOCK,
    I_STUCK_RUN,
    I_CHECK_N,
    I_NOISE_FREE_REPEATS,
    I_LIVE_N,
    I_CONFIRM,
    I_MT_LAG,
    I_MT_LANDING,
    I_MT_BOARD,  # the second finger's surface (the first), or -1: none
    I_N_DRIFT,  # windows an idle desk rests before its drift is followed; 0: never
    I_STILL_RING,  # still windows' means kept (the last of a still run)
    I_N_SETTLE,  # windows a still load is held before it joins the zero
    I_N_OBJECT,  # windows a load as still as the idle desk waits to be an object; 0: no rule
    I_WANDER_WINDOWS,  # the idle windows in a row a yardstick wander is taken over
    I_IDLE_WINDOWS,  # the idle windows whose spreads and wanders make the yardsticks
    I_ZEROED,  # the readings come zeroed: the zero is 0 from the first good sample, no windows
    I_REST_N,  # rest readings whose changes measure each channel's noise (resolution.py)
    I_N_NOISY_EXTRA,  # windows more an object waits where the noise sets the still limit
    I_JUMP_HOLD_N,  # samples in a row a jump is held at most (settings.JUMP_HOLD_S)
    # offsets into pf
    I_PO_MAP,  # (C, 6) channels -> [F_o; M_o]: the matrix (6, C) stored by channel
    I_PO_LIMIT,  # (C,) a channel at or beyond this is saturated
    I_PO_LP_SOS,  # (NS, 6) each
    I_PO_DIFF_SOS,
    I_PO_DET_SOS,
    I_PO_MT_SOS,
    I_PO_LP_ZI,  # (NS, 2) each: the state of a unit step
    I_PO_DIFF_ZI,
    I_PO_DET_ZI,
    I_PO_MT_ZI,
    I_PO_SURF,  # (N_SURF, SURF_F)
    I_PO_LEVER,  # (3, 2) the sway's moment lever
    I_PO_GAIN,  # (6, A) the accelerometers' gain
    I_PO_REST,  # (A,)
    I_PO_ALIMIT,  # (A,)
    # offsets into pi
    I_IO_UP,  # (N_UP,) the upright surfaces' indices
    I_IO_SURF,  # (N_SURF, SURF_I)
    # offsets into sf
    I_SO_LP_ZI,  # (NS, 2, 6) each: a section's two memories, the six lanes side by side
    I_SO_DIFF_ZI,
    I_SO_DET_ZI,
    I_SO_MT_ZI,
    I_SO_DELAY,  # (N_DIFF, 6)
    I_SO_DET_RING,  # (N_RATE, 3)
    I_SO_SWAY,  # (2·SPAN, 2) each
    I_SO_SWAY_DIFF,
    I_SO_WIN_LP,  # (WINDOW, 3): a sample's lanes side by side
    I_SO_WIN_RAW,  # (WINDOW, 6)
    I_SO_GUARD,  # (N_UP,)
    I_SO_COVS,  # (N_SURF, 4, 6)
    I_SO_STEP,  # (C,) each
    I_SO_USED,
    I_SO_LAST_ROW,
    I_SO_PREV_ROW,
    I_SO_MT_HIST,  # (2·LAG + 1, MT_F)
    I_SO_LANDING,  # (2·LAG + 1 + LANDING, 6)
    I_SO_PARTIAL_GAIN,  # (6, A)
    I_SO_TRACE,  # (TRACE_ROWS,) the traced candidates of the sample in flight
    I_SO_STILL_MEANS,  # (I_STILL_RING, 6): a ring of the still run's window means
    I_SO_IDLE_SPREADS,  # (I_IDLE_WINDOWS,) a ring of the idle windows' spreads
    I_SO_IDLE_WANDERS,  # (I_IDLE_WINDOWS,) ... and of their wanders
    I_SO_IDLE_TAIL,  # (I_WANDER_WINDOWS, 4) a ring of the last idle windows: index, force (3)
    I_SO_OBJ_WINDOWS,  # (I_N_OBJECT + 1, 4) a ring of the object run's: spread, force (3)
    I_SO_SCRATCH,  # (I_IDLE_WINDOWS + I_N_OBJECT + 1,) room to sort in
    I_SO_ROUND,  # the zero's rounding floor (ROUND_*: kernel_rounding.py)
    I_SO_REST_SQ,  # (C,): the squared changes of each channel's rest readings, summed
    # offsets into si
    I_JO_CHANGES,  # (C,) each
    I_JO_LEARNING,
    I_JO_WIN_BAD,  # (WINDOW,)
    I_JO_MT_HIST,  # (2·LAG + 1, MT_I)
    N_PI,
) = range(84)
# a surface in pf: the rows of F'z, M'x, M'y of its wrench transform, origin, axes, normal,
# bounds of its outline; in pi: whether the outline is a rectangle, whether (u, v) are the
# desk's (x, y), where its polygon's vertices are in pf and how many
SURF_ROWS, SURF_ORIGIN, SURF_U, SURF_V, SURF_NORMAL, SURF_BOUNDS, SURF_F = 0, 18, 21, 24, 27, 30, 34
SURF_RECT, SURF_DESK_XY, SURF_POLY, SURF_N_POLY, SURF_I = 0, 1, 2, 3, 4
COV_LP, COV_DIFF, COV_DET, COV_DRIFT = range(4)  # the covariances per surface, 6 packed each
# the zero's rounding floor at I_SO_ROUND (made at each tare: candidates.Covariances; read by
# kernel_rounding.py): how many channels keep an offset; the table point from which a
# channel keeps all of it; the floor's sums kept (the surface they are for, −1: none; the
# tared wrench they were made at; the squared distance from it they serve; the sums cz,
# czx, czy, cx, cy); the share a press keeps at a change of d ∈ [0, ½] step (ROUND_TABLE_N +
# 1 points); each channel's spread in steps per unit of wrench (C, 6) and the wrench that
# moves it one table point at most (C, 0: the channel keeps none); per surface and channel
# its offset's terms (N_SURF, C, 5)
ROUND_ACTIVE, ROUND_WHOLE, ROUND_SURFACE, ROUND_W, ROUND_LIMIT, ROUND_SUMS = 0, 1, 2, 3, 9, 10
ROUND_TABLE = 15
ROUND_TABLE_N = 128
ROUND_SPREAD = ROUND_TABLE + ROUND_TABLE_N + 1

# --- state: fixed float slots (sf) --------------------------------------------------------------
S_LAST_T = 0  # the last good sample's time
S_MAX_T = 1  # the latest time of a finite sample so far
S_STUCK_SINCE = 2
S_LAST_STUCK_T = 3
S_ZERO_T = 4  # when the zero was set
S_ZERO = 5  # (6,) the zero of [F_o; M_o]
S_LAST_GOOD = 11  # (6,) the last good resultant, before the inertial wrench is removed
S_RAW = 17  # (6,) the sample in flight: its resultant less the inertial wrench
S_LP = 23  # (6,) its low-passed wrench
S_DET = 29  # (6,) its fast wrench
S_DIFF = 35  # (6,) its differentiated wrench
S_SLOPE = 41  # (3,) the fast force's slope over N_RATE
S_RELEASE = 44  # (3,) ... over N_RELEASE
S_WIN_SPREAD = 47  # the window just ended: its spread, its raw mean (6), its last time
S_WIN_MEAN = 48
S_WIN_T_END = 54
S_EV_T = 55  # an event's time
S_EV_LATEST = 56  # time back: the latest time before it
S_MT_FIRST = 57  # (3,) the first finger's point at the landing
S_MT_SECOND = 60  # (3,) the second finger's fitted point
S_MT_STRAY = 63  # the open contact's farthest change
S_MT_MIN_APART = 64  # how far from the first finger a landing must be
S_MT_END_STRAY = 65  # a contact's stray at its end (EV_CONTACT_END)
S_TARED_W = 66  # (6,) the tared low-passed wrench
S_TARED_Q = 72  # (6,) the tared fast wrench
S_STILL_LO = 78  # (3,) the still run's lowest window mean of the force less the zero
S_STILL_HI = 81  # (3,) ... and highest
S_QUIET_SPREAD = 84  # the idle desk's yardsticks (yardsticks.py): its windows' spread
S_QUIET_WANDER = 85  # ... and how far their means stray
S_OBJ_ZERO = 86  # (6,) the last absorbed object's zero from before it (EV_ABSORBED, EV_LIFTED)
S_OBJ_WEIGHT = 92  # ... its |F|
S_OBJ_F = 93  # (3,) ... its force (EV_ABSORBED: put on or taken off)
S_ZERO_NEXT = 96  # (6,) a zero decided at a window's end for the next sample on (J_ZERO_NEXT)
S_ZERO_T_NEXT = 102  # ... and its time
S_BACK_FROM = 103  # the run of samples whose times went back: its first time
S_BACK_LAST = 104  # ... and its last (inf: no run)
S_JUMP_T = 105  # the last sample held for its jump: its time
S_JUMP_SIZE = 106  # ... and how far it jumped (N, or N·m / arm)
N_SF_FIXED = 107
# --- state: fixed int slots (si) ----------------------------------------------------------------
(
    J_STARTED,  # a good sample has been seen: the filters run
    J_STUCK_CHECK,  # -1 deciding, 0 off (noise-free input), 1 on
    J_SEEN,
    J_SEEN_REPEATS,
    J_REPEATS,
    J_LIVE,
    J_TIME_BACK,
    J_HAVE_PREV,
    J_HAVE_LAST_ROW,
    J_TARED,
    J_RESTING,
    J_DELAY_POS,
    J_DET_POS,
    J_SWAY_POS,
    J_SWAY_DIFF_POS,
    J_WIN_FILL,
    J_WIN_BADS,  # the window just ended: its bad samples
    J_RESTING_OFF,  # the sample in flight ended a window judged here: no resting after it
    J_WINDOW_INDEX,  # windows ended so far, still or not (zero.py: which are in a row)
    J_WINDOWS_SEEN,  # windows judged on (every one before the tare, the still ones after)
    J_STILL_RUN,  # still windows in a row, the load not moved
    J_STILL_POS,  # where the next still mean goes in its ring
    J_STILL_COUNT,  # still means in the ring since the run began (at most I_STILL_RING)
    J_OBJECT_RUN,  # windows a load has been as still as an object (zero.py)
    J_OBJECTS,  # objects absorbed into the zero (zero.py keeps what they were)
    J_ZERO_VERSION,  # how many times the zero was set
    J_IN_CONTACT,
    J_BLOCKED,
    J_N_LEARNING,
    J_DIRTY,
    J_FLAGS,  # the sample in flight's flags
    J_EVENT_AT,
    J_RESUME,
    J_PARTIAL,  # for the pattern J_PARTIAL_PATTERN: 1 its gain is in I_SO_PARTIAL_GAIN, 2 none
    J_PARTIAL_PATTERN,  # the usable readings' bits + 1 whose gain is known; 0: none known
    J_MT_ON,
    J_MT_STARTED,
    J_MT_COUNT,
    J_MT_POS,
    J_MT_PREV_IN,
    J_MT_FLAGGED,
    J_MT_LANDING,
    J_MT_NEED,
    J_MT_ROWS,
    J_MT_HAS_SECOND,
    J_MT_END_FLAGGED,
    J_RESTING_NEXT,  # the window just ended found the load resting: J_RESTING from the next
    J_IDLE_SPREADS_N,  # the idle spreads in their ring, and where the next goes
    J_IDLE_SPREADS_POS,
    J_IDLE_WANDERS_N,
    J_IDLE_WANDERS_POS,
    J_IDLE_TAIL_N,
    J_IDLE_TAIL_POS,
    J_OBJ_WINDOWS_N,  # the object run's windows that count (its last, at most I_N_OBJECT + 1)
    J_OBJ_WINDOWS_POS,
    J_OBJ_RESTING,  # the load rests: its windows so far as still as an object's
    J_OBJ_HELD,  # EV_ABSORBED: the windows whose means made the zero (0: held settle_s)
    J_ZERO_NEXT,  # S_ZERO_NEXT is the zero from the next sample on
    J_REST_N,  # rest readings compared so far (up to I_REST_N)
    J_OBJ_GRACED,  # a window of the object run spread past an object's and was kept (one a run)
    J_OFF_STEPS,  # a channel changed by no whole number of its step: readings not quantised
    J_JUMP,  # JUMP_CALM, JUMP_HELD (the sample before was held for its jump) or JUMP_MOVING
    J_JUMPS,  # readings that jumped and came back within I_JUMP_HOLD_N samples, so far
    J_JUMP_HELD_N,  # the samples held in the latest run of held ones
    N_SI_FIXED,
) = range(65)
# a reading's jump (kernel_channels.jumped): from a calm wrench it is held while it stays
# away, for up to I_JUMP_HOLD_N samples; the next one is taken, and while the wrench keeps
# jumping (a real change) none is held
JUMP_CALM, JUMP_HELD, JUMP_MOVING = range(3)
# the second-finger stage's history of each sample: smoothed wrench and contact (floats), and
# its located, surface and in-contact (ints)
MT_W, MT_X, MT_Y, MT_Z, MT_FORCE, MT_F = 0, 6, 7, 8, 9, 10
MT_LOCATED, MT_SURFACE, MT_INSIDE, MT_I = 0, 1, 2, 3

# --- outputs ------------------------------------------------------------------------------------
# float rows of out_f (then TRACE_ROWS more in trace mode)
OUT_T, OUT_X, OUT_Y, OUT_Z, OUT_FORCE, OUT_SIGMA = range(6)
OUT_X2, OUT_Y2, OUT_Z2, OUT_SHEAR, OUT_DRAG_X, OUT_DRAG_Y, N_OUT_F = range(6, 13)
# int8 rows of out_b
OUT_B_IN_CONTACT, OUT_B_LOCATED, OUT_B_LOCATED2, OUT_B_RESTING = range(4)
OUT_B_SOURCE, OUT_B_PHASE, OUT_B_FLAGS, OUT_B_TRACED, N_OUT_B = range(4, 9)
# the trace rows (after N_OUT_F): |F| low-passed, the rate, and per candidate (force, diff,
# fast) its point (3), whether valid and its 1-σ
TRACE_FORCE, TRACE_RATE, TRACE_CANDIDATES, TRACE_PER_CANDIDATE, TRACE_ROWS = 0, 1, 2, 5, 17

#: a candidate point where a wrench's line of action meets a surface (paper eq. 5), in the
#: surface's frame, with its covariance (eqs. 11-12): a plain tuple read by these field
#: indices (a NamedTuple compiled to code twice as slow here: 18.7 against 9.7 ms a minute);
#: C_INV_FZ is 1/F'z of the wrench it was made from on its surface (0 where none: a fused
#: point, or none), which the rounding floor of the same wrench reuses
Candidate = tuple[int, float, float, float, float, float, float]
C_SURFACE, C_U, C_V, C_VAR_U, C_VAR_V, C_COV_UV, C_INV_FZ = range(7)  # (surface -1: none)
#: a wrench [F; M] held in registers between two stages (six floats)
Wrench = tuple[float, float, float, float, float, float]

"""Analysis of recordings for setting up a desk and reproducing the paper.

- :mod:`~hapticdesk.analysis.thresholds`: F_tth and F_rth from recorded presses (paper §5.2),
  ``hapticdesk thresholds``.
- :mod:`~hapticdesk.analysis.characterize`: noise, natural frequencies, a low-pass cut-off
  and drift of a desk or a bench sensor (:mod:`~hapticdesk.analysis.quiet_windows`,
  :mod:`~hapticdesk.analysis.free_decay`), ``hapticdesk characterize``.
- :mod:`~hapticdesk.analysis.plotting`: a recording's force and contact trace as a PNG (paper
  Figs. 7 and 13), ``hapticdesk plot``; imports matplotlib only when called.
- :mod:`~hapticdesk.analysis.known_weight`: load cells' gains and places fitted to a known
  weight (its rests: :mod:`~hapticdesk.analysis.weight_rests`; the profile written:
  :mod:`~hapticdesk.analysis.calibrated_profile`), ``hapticdesk calibrate``.
- :mod:`~hapticdesk.analysis.setup_check`: a profile checked against presses at known points.

Everything works on recordings without ground truth (real desks); the simulator's truth is
used only where a recording has it (plots) and by the tests.
"""

"""CAN logs, one module per format (STYLE 22), chosen by the file's suffix in
:mod:`~hapticdesk.canbus.logs.formats`:

- :mod:`~hapticdesk.canbus.logs.python_can_logs` python-can's formats (``.asc`` Vector ASCII,
  ``.blf`` Vector binary, ``.trc`` PEAK trace, ``.log`` candump ``-l``; each also ``.gz``);
- :mod:`~hapticdesk.canbus.logs.candump_text` candump's printed text, through cantools;
- :mod:`~hapticdesk.canbus.logs.log_files` opening a log and reading its lines, bounded;
- :mod:`~hapticdesk.canbus.logs.skipped` what the readers skip, counted and said;
- :mod:`~hapticdesk.canbus.logs.writer` writing frames to a python-can log;
- :mod:`~hapticdesk.canbus.logs.desk_samples` a log decoded into a desk's samples (a
  :class:`~hapticdesk.files.recording.Recording`, or a finite source for a replay).
"""

"""``hapticdesk run``: a source, the estimator, the gesture engine and the dispatcher, wired.

:mod:`~hapticdesk.runtime.source` is the shape every source has, :mod:`.source_spec` picks one
from ``--source KIND:ARGUMENT``, :mod:`.service` runs the flow, :mod:`.dispatcher` runs the
actions in their own threads.
"""

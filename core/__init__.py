"""hapticdesk: a desk on force/torque sensors as a touch and gesture surface.

The flow runs one way: source → estimator → gestures → dispatcher → actions
(see the README and ../shared/DESIGN.md). Start with :mod:`hapticdesk.estimator`.
"""

__version__ = "0.1.0"

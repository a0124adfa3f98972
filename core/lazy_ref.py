"""A lazy ``"module:attr"`` reference and the one resolver for it.

Plugins register their factories, validators and recognizers as objects or as such text, so a
scene imports only what it uses (python-can's ``BACKENDS`` habit, STYLE.md 4 and 15). The
registry resolves them when a run first uses one; a layout resolves a gesture's recognizer; the
child process of an isolated action resolves its factory. This module imports nothing of the
project, so any layer may use it.
"""

from __future__ import annotations

import importlib
from types import ModuleType
from typing import Any


def resolve(ref: Any) -> Any:
    """A lazy ``"module:attr"`` (or ``"module"``) reference imported, or ``ref`` itself when
    it is not text. Import problems propagate (ImportError, AttributeError): the caller says
    whose reference it was."""
    if not isinstance(ref, str):
        return ref
    module_name, _, attr = ref.partition(":")
    obj: Any = importlib.import_module(module_name)
    for part in attr.split(".") if attr else ():
        obj = getattr(obj, part)
    return obj


def is_loadable(ref: object) -> bool:
    """True for what :func:`resolve` can give a caller something from: a callable, a module or
    a ``"module:attr"`` text."""
    return ref is not None and (callable(ref) or isinstance(ref, str | ModuleType))

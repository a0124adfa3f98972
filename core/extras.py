"""hapticdesk's optional parts (its extras) and the command that installs each.

A scene imports only what it uses: matplotlib for a drawing, starlette and uvicorn for the
page, amqtt for the demo's broker. When one is missing the user is told which extra brings it,
``pip install 'hapticdesk[plot]'``, never Python's "No module named …". The table is the
package's own metadata (pyproject.toml's optional dependencies), so an extra added there is
named here too.
"""

from __future__ import annotations

import functools
import importlib.metadata
import re

#: distributions whose import name is not their own name
IMPORT_NAMES = {
    "pyserial": "serial",
    "ruamel.yaml": "ruamel",
    "python-can": "can",
    "paho-mqtt": "paho",
    "pyyaml": "yaml",
}
#: extras that gather others (the test suite's); never the one to name
GATHERING_EXTRAS = frozenset({"test"})
_REQUIREMENT = re.compile(r"\s*([A-Za-z0-9_.\-]+)[^;]*;.*\bextra\s*==\s*['\"]([\w.\-]+)['\"]")


@functools.cache
def extras() -> dict[str, str]:
    """Import name -> the first extra that installs it (empty when hapticdesk's metadata
    cannot be read, e.g. run from a source tree never installed)."""
    try:
        requires = importlib.metadata.requires("hapticdesk") or []
    except importlib.metadata.PackageNotFoundError:
        return {}
    found: dict[str, str] = {}
    for requirement in requires:
        m = _REQUIREMENT.match(requirement)
        if m is None or m.group(2) in GATHERING_EXTRAS:
            continue
        distribution = m.group(1).lower()
        name = IMPORT_NAMES.get(distribution, distribution.replace("-", "_"))
        found.setdefault(name, m.group(2))
    return found


def install_hint(module: str | None) -> str | None:
    """What to say when ``module`` cannot be imported: which extra brings it and the command
    that installs it; None when no extra does (a broken install, a bug)."""
    top = (module or "").split(".")[0]
    extra = extras().get(top)
    if extra is None:
        return None
    return (
        f"{top} is not installed; it comes with hapticdesk's `{extra}` extra: "
        f"pip install 'hapticdesk[{extra}]'"
    )


def require(*modules: str, needed_by: str) -> None:
    """Import ``modules`` now; a missing one is a ConfigError that names ``needed_by`` and the
    extra to install (for a part that would otherwise fail later, in a thread of its own)."""
    import importlib

    from hapticdesk.errors import ConfigError

    for module in modules:
        try:
            importlib.import_module(module)
        except ImportError:
            hint = install_hint(module) or f"{module} is not installed"
            raise ConfigError(None, f"{needed_by}: {hint}") from None

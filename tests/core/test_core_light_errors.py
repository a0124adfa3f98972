"""The error type every room raises, and the checks of marked values, come without the YAML
library: ``hapticdesk --help`` and a plugin that only checks its options import
:mod:`hapticdesk.errors` and :mod:`hapticdesk.files.validators`, never ``yaml`` (issue 34)."""

from __future__ import annotations

import pytest

PROBE = """
import contextlib, io, json, sys
{statement}
print(json.dumps([m for m in ("yaml", "numpy") if m in sys.modules]))
"""

HELP = """
from hapticdesk.cli import main
with contextlib.redirect_stdout(io.StringIO()):
    try:
        main(["--help"])
    except SystemExit:
        pass
"""


def _loaded(python_probe, statement: str) -> list[str]:
    return python_probe(PROBE.format(statement=statement), timeout=60)


def test_the_errors_and_the_validators_import_no_yaml(python_probe):
    assert _loaded(python_probe, "import hapticdesk.errors, hapticdesk.files.validators") == []


def test_help_imports_no_yaml(python_probe):
    assert "yaml" not in _loaded(python_probe, HELP)


def test_loading_yaml_still_marks_positions_for_the_validators(tmp_path):
    from hapticdesk.errors import ConfigError
    from hapticdesk.files.validators import number
    from hapticdesk.files.yamlfile import load_marked_yaml

    path = tmp_path / "desk.yaml"
    path.write_text("name: d\nrate: fast\n", encoding="utf-8")
    doc = load_marked_yaml(path)
    with pytest.raises(ConfigError) as err:
        number(doc, "rate", "the desk")
    assert str(err.value.where) == f"{path}:2:7"
    assert "must be a number" in err.value.message

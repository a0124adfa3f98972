"""The package list in pyproject.toml ships every folder of code.

setuptools is given the packages by name (the import package lives in core/, not hapticdesk/),
so a new sub-package that is not added there works in an editable install and is missing from
a wheel: this test fails first.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def _declared() -> tuple[set[str], dict[str, str]]:
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    return set(config["packages"]), dict(config["package-dir"])


def _package_name(folder: Path, package_dir: dict[str, str]) -> str:
    for name, where in package_dir.items():
        base = ROOT / where
        if folder == base or base in folder.parents:
            rest = folder.relative_to(base).parts
            return ".".join((name, *rest))
    raise AssertionError(f"{folder} is under no package-dir root")


def test_every_folder_of_python_code_is_a_declared_package() -> None:
    packages, package_dir = _declared()
    missing = []
    for root in ("core", "plugins"):
        for module in (ROOT / root).rglob("*.py"):
            if "__pycache__" in module.parts:
                continue
            name = _package_name(module.parent, package_dir)
            if name not in packages:
                missing.append(f"{module.parent.relative_to(ROOT)} ({name})")
    assert not sorted(set(missing)), f"add to [tool.setuptools] packages: {sorted(set(missing))}"


def test_every_declared_package_exists() -> None:
    packages, package_dir = _declared()
    for name in packages:
        root = max((n for n in package_dir if name == n or name.startswith(n + ".")), key=len)
        folder = ROOT / package_dir[root] / Path(*name[len(root) :].lstrip(".").split(".") or [])
        assert folder.is_dir(), f"{name}: no folder {folder.relative_to(ROOT)}"

"""The site's nav holds the pages other work brings (serial boards, load cells, force plates,
strokes, Home Assistant, security, performance) before they arrive: until a page is in docs/,
its entry is left out of the nav, so ``mkdocs build --strict`` still fails on any other page
the nav names and does not find. A MkDocs hook (mkdocs.yml ``hooks:``).
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

log = logging.getLogger("mkdocs.hooks.nav")

#: pages the nav names ahead of their arrival
EXPECTED_PAGES = frozenset(
    {
        "serial.md",
        "loadcells.md",
        "forceplates.md",
        "strokes.md",
        "homeassistant.md",
        "security.md",
        "performance.md",
    }
)


def present(nav: list[Any], docs: Path) -> list[Any]:
    """``nav`` without the entries of expected pages that are not in ``docs`` yet."""
    kept: list[Any] = []
    for entry in nav:
        if isinstance(entry, dict):
            [(title, value)] = entry.items()
            if isinstance(value, list):
                value = present(value, docs)
                if value:
                    kept.append({title: value})
                continue
            entry_file = value
        else:
            entry_file = entry
        if entry_file in EXPECTED_PAGES and not (docs / entry_file).is_file():
            log.info("nav: %s is not in docs/ yet; left out", entry_file)
            continue
        kept.append(entry)
    return kept


def on_config(config: Any) -> Any:
    if config.get("nav"):
        config["nav"] = present(config["nav"], Path(config["docs_dir"]))
    return config

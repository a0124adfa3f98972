"""The ``plugins`` command: what is installed, with versions, and what each plugin provides."""

from __future__ import annotations

import argparse
import json
import os

from hapticdesk.plugin_loading import load_registry
from hapticdesk.registered import KINDS
from hapticdesk.registry import DISABLE_AUTOLOAD_ENV


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--json", action="store_true", help="one JSON object per plugin")
    parser.add_argument(
        "--strict", action="store_true", help="a plugin that fails to load is fatal"
    )


def run(args: argparse.Namespace) -> int:
    # a name two plugins register is listed as an error here, not a stop: this is where one
    # looks to find out which plugins clash
    registry = load_registry(strict=args.strict, conflicts_fatal=False)
    status = 1 if registry.errors else 0
    if args.json:
        for info in registry.plugins.values():
            print(json.dumps(info.to_dict()))
        for warning in registry.warnings:
            print(json.dumps({"warning": warning}))
        for error in registry.errors:
            print(json.dumps({"error": error}))
        return status
    for info in registry.plugins.values():
        print(f"{info.name} {info.version} ({info.origin})")
        for kind in KINDS:
            for name in info.provides[kind]:
                record = getattr(registry, kind)[name]
                what = "section" if kind == "layout_sections" else kind[:-1]
                print(f"  {what:<10} {name:<12} {record.description}")
        others = [h for h in info.hooks if not h.startswith("register_")]
        if others:
            print(f"  hooks      {', '.join(others)}")
    if os.environ.get(DISABLE_AUTOLOAD_ENV):
        print(f"third-party plugins are not loaded: {DISABLE_AUTOLOAD_ENV} is set")
    for warning in registry.warnings:
        print(f"warning: {warning}")
    for error in registry.errors:
        print(f"error: {error}")
    return status

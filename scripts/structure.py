#!/usr/bin/env python3
"""The project's structure in numbers: its largest module, its longest function, and the circles
among its imports (any import, at module level or inside a function).

    python scripts/structure.py [--limit-lines N] [--limit-function N] [--list N] [--hold all|doors]

Counts the code that ships (core/ as ``hapticdesk``, plugins/ as ``hapticdesk.plugins``), not
tests or scripts. Lines are physical lines of the file; a function's length runs from its
``def`` (decorators included) to its last line. Exits 1 when a limit is passed or a circle
exists, or a core module imports a plugin, so CI can hold it (CI holds `--hold all`: every
limit, the circles and the plugin door; `--hold doors` holds only the last two).
"""

from __future__ import annotations

import argparse
import ast
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = {"core": "hapticdesk", "plugins": "hapticdesk.plugins"}


def modules() -> dict[str, Path]:
    """Dotted module name -> file, for every module that ships."""
    out = {}
    for folder, package in PACKAGES.items():
        for path in sorted((ROOT / folder).rglob("*.py")):
            parts = list(path.relative_to(ROOT / folder).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            out[".".join([package, *parts])] = path
    return out


def imports_of(name: str, path: Path, known: set[str]) -> set[str]:
    """The project's modules ``name`` imports, anywhere in the file."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    is_package = path.name == "__init__.py"
    found = set()
    for node in ast.walk(tree):
        targets: list[str] = []
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                here = name.split(".") if is_package else name.split(".")[:-1]
                up = here[: len(here) - (node.level - 1)]
                base = ".".join(up + ([base] if base else []))
            targets = [base] + [f"{base}.{a.name}" for a in node.names]
        for target in targets:
            while target and target not in known:
                target = target.rpartition(".")[0]
            if target and target != name:
                found.add(target)
    return found


def circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected groups of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []
    counter = [0]

    def visit(v: str) -> None:
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            group = []
            while True:
                w = stack.pop()
                on.discard(w)
                group.append(w)
                if w == v:
                    break
            if len(group) > 1:
                out.append(sorted(group))

    sys.setrecursionlimit(10_000)
    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def functions(path: Path) -> list[tuple[int, str, int]]:
    """(length, name, first line) of every function and method in the file."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            first = min([node.lineno] + [d.lineno for d in node.decorator_list])
            out.append((node.end_lineno - first + 1, node.name, first))
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--limit-lines", type=int, default=400)
    parser.add_argument("--limit-function", type=int, default=60)
    parser.add_argument("--list", type=int, default=5, help="how many of each to list")
    parser.add_argument(
        "--hold",
        choices=("all", "doors"),
        default="all",
        help="what fails the run: every limit (all), or only import circles and a core module "
        "naming a plugin (doors: what CI holds while modules are still being split)",
    )
    args = parser.parse_args()
    found = modules()
    known = set(found)
    graph = {name: imports_of(name, path, known) for name, path in found.items()}
    # a package's own __init__ importing its submodules is how packages are made, not a circle
    for name in graph:
        graph[name] = {t for t in graph[name] if not name.startswith(t + ".")}
    sizes = sorted(
        (
            (len(p.read_text(encoding="utf-8").splitlines()), p.relative_to(ROOT))
            for p in found.values()
        ),
        reverse=True,
    )
    longest = sorted(
        (
            (n, f"{p.relative_to(ROOT)}:{line} {fn}")
            for p in found.values()
            for n, fn, line in functions(p)
        ),
        reverse=True,
    )
    loops = circles(graph)
    # the core reaches plugins only through the hooks (registry strings, entry points)
    named_plugins = sorted(
        f"{name} -> {target}"
        for name, targets in graph.items()
        if not name.startswith(PACKAGES["plugins"])
        for target in targets
        if target.startswith(PACKAGES["plugins"])
    )
    print(f"modules {len(found)}; largest {sizes[0][0]} lines ({sizes[0][1]})")
    for n, p in sizes[: args.list]:
        print(f"  {n:>5}  {p}")
    print(f"functions {len(longest)}; longest {longest[0][0]} lines ({longest[0][1]})")
    for n, where in longest[: args.list]:
        print(f"  {n:>5}  {where}")
    print(f"import circles {len(loops)}")
    for loop in loops:
        print("  " + " <-> ".join(loop))
    print(f"core modules importing a plugin {len(named_plugins)}")
    for line in named_plugins:
        print("  " + line)
    over = [s for s in sizes if s[0] > args.limit_lines]
    long = [f for f in longest if f[0] > args.limit_function]
    print(
        f"over {args.limit_lines} lines: {len(over)} modules; "
        f"over {args.limit_function} lines: {len(long)} functions"
    )
    if args.hold == "doors":
        return 1 if loops or named_plugins else 0
    return 1 if over or long or loops or named_plugins else 0


if __name__ == "__main__":
    sys.exit(main())

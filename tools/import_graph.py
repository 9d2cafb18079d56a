"""Import cycles inside aquasim_py and aquasim_protocols, read from the source with ``ast``
(nothing is imported).

Every ``import`` / ``from ... import`` between two of their modules is an edge, tagged "top"
(module level, run at import), "lazy" (inside a function) or "typing" (under
``if TYPE_CHECKING``). Compiled extension modules (a ``.pyi`` stub or a ``.c`` source beside
the package's ``.py`` files) are modules too, without imports of their own, so that
``from . import _ext`` is an edge to ``_ext``, not to the package. Cycles are counted and
listed for the top-level edges and for all edges; the exit status is 1 if there is any cycle
among all edges, lazy and typing-only ones included (``make lint`` runs this, and so CI).

    python tools/import_graph.py            # cycles (none expected)
    python tools/import_graph.py --edges    # also every edge
"""

from __future__ import annotations

import argparse
import ast
import sys
from pathlib import Path

import networkx as nx

ROOT = Path(__file__).resolve().parents[1]
#: source folder -> package name it installs as (pyproject.toml's package-dir)
SOURCES = {ROOT / "aquasim_py": "aquasim_py", ROOT / "protocols": "aquasim_protocols"}


def modules(sources: dict[Path, str] | None = None) -> dict[str, Path]:
    """Module name -> file, for every .py file of the packages (packages as their __init__),
    and every compiled extension (its ``.pyi`` stub or ``.c`` source) that has no .py file."""
    out: dict[str, Path] = {}
    for folder, pkg in (SOURCES if sources is None else sources).items():
        for pattern in ("*.py", "*.pyi", "*.c"):
            for f in sorted(folder.rglob(pattern)):
                parts = list(f.relative_to(folder).with_suffix("").parts)
                if parts[-1] == "__init__":
                    parts = parts[:-1]
                out.setdefault(".".join([pkg, *parts]), f)
    return out


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def imports(name: str, path: Path, known: set[str]) -> list[tuple[str, str]]:
    """(imported aquasim_py module, kind) for each import statement of one module."""
    is_pkg = path.name == "__init__.py"
    package = name if is_pkg else name.rpartition(".")[0]
    found: list[tuple[str, str]] = []

    def target(mod: str) -> str | None:
        # the longest known module prefix (``from a.b import c`` may name module a.b.c or a name in a.b)
        while mod and mod not in known:
            mod = mod.rpartition(".")[0]
        return mod or None

    def visit(node: ast.AST, kind: str) -> None:
        for child in ast.iter_child_nodes(node):
            k = kind
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)) and kind == "top":
                k = "lazy"
            if isinstance(child, ast.If) and _is_type_checking(child.test):
                for sub in child.body:
                    visit_stmt(sub, "typing")
                for sub in child.orelse:
                    visit_stmt(sub, k)
                continue
            visit_stmt(child, k)

    def visit_stmt(node: ast.AST, kind: str) -> None:
        if isinstance(node, ast.Import):
            for a in node.names:
                t = target(a.name)
                if t:
                    found.append((t, kind))
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - (node.level - 1)]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            for a in node.names:
                t = target(f"{mod}.{a.name}") if a.name != "*" else None
                t = t if t and t != package else target(mod)
                if t:
                    found.append((t, kind))
        else:
            visit(node, kind)

    if path.suffix != ".py":  # an extension module imports nothing of ours
        return []
    visit(ast.parse(path.read_text(), str(path)), "top")
    return [(t, k) for t, k in found if t != name]


def graph(sources: dict[Path, str] | None = None) -> nx.MultiDiGraph:
    """Every module of ``sources`` (folder -> package name; default this repository's) with an
    edge per import between two of them, tagged with its kind."""
    mods = modules(sources)
    g: nx.MultiDiGraph = nx.MultiDiGraph()
    g.add_nodes_from(mods)
    for name, path in mods.items():
        for t, kind in sorted(set(imports(name, path, set(mods)))):
            g.add_edge(name, t, kind=kind)
    return g


def cycles(g: nx.MultiDiGraph, kinds: set[str]) -> list[list[str]]:
    """The simple cycles among the edges of ``kinds``, each rotated to start at its smallest
    module name (networkx's starting point depends on set order, so on the hash seed)."""
    sub = nx.DiGraph((u, v) for u, v, k in g.edges(data="kind") if k in kinds)
    rotated = []
    for c in nx.simple_cycles(sub):
        i = c.index(min(c))
        rotated.append(c[i:] + c[:i])
    return sorted(rotated)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--edges", action="store_true", help="print every edge")
    args = ap.parse_args(argv)
    g = graph()
    if args.edges:
        for u, v, k in sorted(g.edges(data="kind")):
            print(f"{u} -> {v} [{k}]")
    top = cycles(g, {"top"})
    every = cycles(g, {"top", "lazy", "typing"})
    print(f"{g.number_of_nodes()} modules, {g.number_of_edges()} imports")
    print(f"cycles among module-level imports: {len(top)}")
    for c in top:
        print("  " + " -> ".join([*c, c[0]]))
    print(f"cycles among all imports (with lazy and TYPE_CHECKING ones): {len(every)}")
    for c in every:
        print("  " + " -> ".join([*c, c[0]]))
    return 1 if every else 0


if __name__ == "__main__":
    sys.exit(main())

"""Griffe extension for the API reference: the docstrings' Sphinx roles as Markdown links.

The code's docstrings cross-reference with Sphinx roles (``:func:`run_scenario```,
``:class:`~.bathymetry.FluidBottom```, ``:mod:`aquasim_py.outdir```), which Markdown would show
as they are typed. Each role becomes the name in code font, linked where the reference renders
that object (an *optional* autoref: a name the reference does not show stays plain code, with
no warning, as Sphinx shows an unresolved role). Names are resolved as Sphinx resolves them:
in the scope of the documented object (its module's imports and members), a leading dot
relative to the enclosing modules, otherwise as a full dotted path.

A reST literal block (a paragraph ending in ``::``, then a block indented under it) becomes
a fenced Markdown code block at the paragraph's indentation, so that it stays a code block
inside a list item too (highlighted as Python when it parses as Python); the ``::`` becomes a
single colon.
"""

from __future__ import annotations

import ast
import re
import textwrap
from typing import Any

import griffe

_ROLE = re.compile(r":(?:py:)?(?:func|class|mod|meth|attr|data|exc|obj|const):`(?P<body>[^`]+)`")
_BULLET = re.compile(r"^(\s*)([-*+]|\d+\.)\s+")


def _find(root: griffe.Object, path: str) -> griffe.Object | griffe.Alias | None:
    """The object at a dotted ``path`` in the loaded collection, or None."""
    try:
        return root.modules_collection[path]
    except (KeyError, ValueError, griffe.AliasResolutionError, griffe.CyclicAliasError):
        return None


def _resolve(obj: griffe.Object | griffe.Alias, target: str) -> str | None:
    """The full path of the object ``target`` names in the docstring of ``obj``, or None."""
    if target.startswith("."):
        # relative: the name under the enclosing modules, innermost first
        module = obj.module if not isinstance(obj, griffe.Module) else obj
        name = target.lstrip(".")
        parts = module.path.split(".")
        for i in range(len(parts), 0, -1):
            found = _find(obj, ".".join(parts[:i] + [name]))
            if found is not None:
                return found.path
        return None
    head, _, rest = target.partition(".")
    scope = obj if isinstance(obj, griffe.Object) else obj.target
    try:
        full = scope.resolve(head)
    except (griffe.NameResolutionError, griffe.AliasResolutionError, AttributeError):
        full = head
    path = f"{full}.{rest}" if rest else full
    found = _find(obj, path)
    return found.path if found is not None else None


def _rewrite(obj: griffe.Object | griffe.Alias, text: str) -> str:
    def link(m: re.Match[str]) -> str:
        body = m["body"].strip()
        explicit = re.fullmatch(r"(?P<title>.+?)\s*<(?P<target>[^>]+)>", body)
        if explicit:
            title, target = explicit["title"], explicit["target"]
        else:
            target = body.lstrip("~")
            title = target.rsplit(".", 1)[-1] if body.startswith("~") else target.lstrip(".")
        path = _resolve(obj, target.lstrip("~"))
        if path is None:
            return f"`{title}`"
        return f'<autoref identifier="{path}" optional><code>{title}</code></autoref>'

    return _literal_blocks(_ROLE.sub(link, text))


def _indent(line: str) -> int:
    return len(line) - len(line.lstrip())


def _is_python(code: str) -> bool:
    """Whether a literal block is Python source (highlighted as such) rather than TOML or text."""
    try:
        ast.parse(code)
    except SyntaxError:
        return False
    return True


def _literal_blocks(text: str) -> str:
    """Each reST literal block as a fenced code block (see the module docstring)."""
    lines = text.split("\n")
    out: list[str] = []
    i = 0
    while i < len(lines):
        line = lines[i]
        i += 1
        if not line.rstrip().endswith("::"):
            out.append(line)
            continue
        head = line.rstrip()[:-2].rstrip()
        if head:
            out.append(head + ":")
        # the paragraph's indentation: its own, or its list item's content column
        bullet = _BULLET.match(line)
        base = len(bullet.group(0)) if bullet else _indent(line)
        j = i
        while j < len(lines) and not lines[j].strip():
            j += 1
        block_end = j
        while block_end < len(lines) and (not lines[block_end].strip() or _indent(lines[block_end]) > base):
            block_end += 1
        while block_end > j and not lines[block_end - 1].strip():
            block_end -= 1
        if block_end == j:  # no indented block follows: an ordinary colon
            continue
        pad = " " * base
        body = textwrap.dedent("\n".join(lines[j:block_end]))
        fence = pad + "```" + ("python" if _is_python(body) else "")
        out += ["", fence, *(pad + b if b else b for b in body.split("\n")), pad + "```"]
        i = block_end
    return "\n".join(out)


class SphinxRoles(griffe.Extension):
    """Rewrite every docstring of a loaded package once the whole package is known."""

    def on_package(self, *, pkg: griffe.Module, **kwargs: Any) -> None:
        seen: set[int] = set()
        stack: list[griffe.Object] = [pkg]
        while stack:
            obj = stack.pop()
            if id(obj) in seen:
                continue
            seen.add(id(obj))
            if obj.docstring is not None:
                obj.docstring.value = _rewrite(obj, obj.docstring.value)
            stack.extend(m for m in obj.members.values() if not m.is_alias)

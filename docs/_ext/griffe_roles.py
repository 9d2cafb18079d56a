"""Griffe extension for the API reference: the docstrings' Sphinx roles as Markdown links.

The code's docstrings cross-reference with Sphinx roles (``:func:`run_scenario```,
``:class:`~.bathymetry.FluidBottom```, ``:mod:`aquasim_py.outdir```), which Markdown would show
as they are typed. Each role becomes the name in code font, linked where the reference renders
that object (an *optional* autoref: a name the reference does not show stays plain code, with
no warning, as Sphinx shows an unresolved role). Names are resolved as Sphinx resolves them:
in the scope of the documented object (its module's imports and members), a leading dot
relative to the enclosing modules, otherwise as a full dotted path.

A reST literal-block marker (a line ending in ``::``) becomes a single colon: the indented
block after it is a Markdown code block already.
"""

from __future__ import annotations

import re
from typing import Any

import griffe

_ROLE = re.compile(r":(?:py:)?(?:func|class|mod|meth|attr|data|exc|obj|const):`(?P<body>[^`]+)`")
_LITERAL = re.compile(r"(?<=\S)::$", re.MULTILINE)  # "Example::" -> "Example:"
_BARE_LITERAL = re.compile(r"^\s*::\s*$\n?", re.MULTILINE)  # a line holding only "::"


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

    text = _ROLE.sub(link, text)
    text = _BARE_LITERAL.sub("", text)
    return _LITERAL.sub(":", text)


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

"""Scenario errors: :class:`ScenarioError` (defined in the leaf module :mod:`aquasim_py.errors`)
and the translation of pydantic's validation errors into one line ``FILE: KEY.PATH: problem``
(the key path as the file spells it, did-you-mean hints for unknown keys)."""

from __future__ import annotations

import difflib
import math
import re
from collections.abc import Iterable, Sequence
from typing import Any, NoReturn

from pydantic import BaseModel, ValidationError

from aquasim_py.errors import ScenarioError

__all__ = ["ScenarioError", "format_key_path", "raise_validation", "show", "toml_type"]


def format_key_path(loc: Iterable[str | int]) -> str:
    """``["nodes", 1, "count"]`` -> ``nodes[1].count``."""
    s = ""
    for el in loc:
        if isinstance(el, int):
            s += f"[{el}]"
        else:
            s += f".{el}" if s else str(el)
    return s


def toml_type(v: Any) -> str:
    """The TOML word for a value's type (for messages)."""
    if isinstance(v, bool):
        return "boolean"
    if isinstance(v, int):
        return "integer"
    if isinstance(v, float):
        return "float"
    if isinstance(v, str):
        return "string"
    if isinstance(v, list):
        return "array"
    if isinstance(v, dict):
        return "table"
    return type(v).__name__


def show(v: Any) -> str:
    """A value as a message shows it (TOML words for booleans, tables and arrays; short)."""
    if isinstance(v, float) and math.isnan(v):
        return "nan"
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (dict, list)):
        return f"a {toml_type(v)}"
    s = repr(v)
    return s if len(s) <= 60 else s[:57] + "..."


_TYPE_WORDS = {
    "float_type": "a number",
    "float_parsing": "a number",
    "int_type": "an integer",
    "int_parsing": "an integer",
    "int_from_float": "an integer",
    "string_type": "a string",
    "bool_type": "true or false",
    "list_type": "an array",
    "dict_type": "a table",
    "model_type": "a table",
    "model_attributes_type": "a table",
}
_UNION_WORDS = {"sound_speed": "sound-speed profile", "placement": "placement kind", "mobility": "mobility model"}


def _clean_loc(loc: Sequence[str | int], raw: Any) -> list[str | int]:
    """Pydantic's error location minus the tags of discriminated unions (walks the raw input)."""
    out: list[str | int] = []
    cur = raw
    for el in loc:
        if isinstance(cur, dict):
            if el in cur:
                out.append(el)
                cur = cur[el]
                continue
            if isinstance(el, str) and el in (cur.get("model"), cur.get("kind")):
                continue  # a union tag, not a key of the file
            out.append(el)
            cur = None
        elif isinstance(cur, list) and isinstance(el, int) and -len(cur) <= el < len(cur):
            out.append(el)
            cur = cur[el]
        else:
            out.append(el)
            cur = None
    return out


def _missing_hint(raw: Any, loc: Sequence[str | int], model: type[BaseModel] | None) -> str:
    """For a required key that is missing: an unknown key beside it that looks like a
    misspelling of it (``duraton_s`` for ``duration_s``), as a hint; "" when there is none."""
    parent = raw
    for el in loc[:-1]:
        if isinstance(parent, dict):
            parent = parent.get(el)
        elif isinstance(parent, list) and isinstance(el, int) and -len(parent) <= el < len(parent):
            parent = parent[el]
        else:
            return ""
    if not isinstance(parent, dict) or not isinstance(loc[-1], str):
        return ""
    allowed = set(_allowed_keys(model, loc[:-1])) if model is not None else set()
    unknown = [k for k in parent if isinstance(k, str) and k not in allowed and k != loc[-1]]
    near = difflib.get_close_matches(loc[-1], unknown, n=1)
    return f" (found {near[0]!r}: did you mean {loc[-1]!r}?)" if near else ""


def _message(
    err: dict[str, Any], loc: list[str | int], model: type[BaseModel] | None, raw: Any = None
) -> tuple[list[str | int], str]:
    typ = err["type"]
    ctx = err.get("ctx") or {}
    inp = err.get("input")
    if typ == "missing":
        if loc == ["nodes"]:
            return loc, "at least one node group is required (add a [[nodes]] table)"
        return loc, "required key missing" + _missing_hint(raw, loc, model)
    if typ == "extra_forbidden":
        msg = "unknown key"
        keys = _allowed_keys(model, loc[:-1]) if model is not None else []
        if keys and isinstance(loc[-1], str):
            near = difflib.get_close_matches(loc[-1], keys, n=1)
            msg += f" (did you mean {near[0]!r}?)" if near else f" (allowed: {', '.join(keys)})"
        return loc, msg
    if typ in ("greater_than_equal", "greater_than", "less_than_equal", "less_than"):
        op = {"greater_than_equal": ">=", "greater_than": ">", "less_than_equal": "<=", "less_than": "<"}[typ]
        bound = next(iter(ctx.values()))
        return loc, f"must be {op} {bound} (got {show(inp)})"
    if typ == "finite_number":
        return loc, f"must be a finite number (got {show(inp)})"
    if typ in _TYPE_WORDS:
        got = show(inp)
        return loc, f"expected {_TYPE_WORDS[typ]} (got {toml_type(inp)} {got})" if not isinstance(
            inp, (list, dict)
        ) else f"expected {_TYPE_WORDS[typ]} (got {got})"
    if typ == "literal_error":
        return loc, f"must be one of {ctx.get('expected')} (got {show(inp)})"
    if typ == "union_tag_invalid":
        what = _UNION_WORDS.get(str(loc[-1]) if loc else "", "value")
        disc = str(ctx.get("discriminator", "")).strip("'")
        return loc + [disc], f"unknown {what} {ctx.get('tag')!r} (expected one of {ctx.get('expected_tags')})"
    if typ == "union_tag_not_found":
        disc = str(ctx.get("discriminator", "")).strip("'")
        return loc + [disc], "required key missing"
    if typ in ("too_short", "too_long"):
        want = f"at least {ctx.get('min_length')}" if typ == "too_short" else f"at most {ctx.get('max_length')}"
        if typ == "too_short" and ctx.get("actual_length") == 0 and loc == ["nodes"]:
            return loc, "at least one node group is required"
        return loc, f"must have {want} entries (got {ctx.get('actual_length')})"
    msg = err.get("msg", "invalid value")
    msg = re.sub(r"^(Value error|Assertion failed), ", "", msg)
    return loc, msg[:1].lower() + msg[1:]


def _allowed_keys(model: type[BaseModel] | None, loc: Sequence[str | int]) -> list[str]:
    """Field names of the (sub)model at ``loc``, for "did you mean" hints (best effort)."""
    import typing

    tp: Any = model
    for el in loc:
        tp = _unwrap(tp)
        if isinstance(el, int):
            args = typing.get_args(tp)
            tp = args[0] if args else None
            continue
        if isinstance(tp, type) and issubclass(tp, BaseModel) and el in tp.model_fields:
            tp = tp.model_fields[el].annotation
        else:
            return []
    tp = _unwrap(tp)
    if isinstance(tp, type) and issubclass(tp, BaseModel):
        return list(tp.model_fields)
    return []


def _unwrap(tp: Any) -> Any:
    import types
    import typing

    while True:
        origin = typing.get_origin(tp)
        if origin is typing.Annotated:
            tp = typing.get_args(tp)[0]
        elif origin in (typing.Union, types.UnionType):
            args = [a for a in typing.get_args(tp) if a is not type(None)]
            if len(args) != 1:
                return None  # a real union: cannot tell which member without the data
            tp = args[0]
        else:
            return tp


def raise_validation(
    exc: ValidationError, raw: Any, file: Any, prefix: Sequence[str | int] = (), model: type[BaseModel] | None = None
) -> NoReturn:
    """Re-raise pydantic's first error as a :class:`ScenarioError` (the first problem is the one
    to fix: one line)."""
    err = exc.errors(include_url=False)[0]
    loc = _clean_loc(list(err["loc"]), raw)
    loc, msg = _message(dict(err), loc, model, raw)
    raise ScenarioError(file, format_key_path(list(prefix) + loc), msg) from None

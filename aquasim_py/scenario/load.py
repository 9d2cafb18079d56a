"""Reading scenarios: TOML, ``--set`` overrides, ``[variants.NAME]`` override sets, sweep grid keys.

``load(path, overrides=[...], seed=None, variant=None)`` reads the file with :mod:`tomllib`,
applies overrides, validates with the strict models of :mod:`aquasim_py.scenario.schema` and
the cross-section checks of :mod:`aquasim_py.scenario.validate`. Every user mistake raises
:class:`ScenarioError` naming the file, the key path (``nodes[1].count``) and the problem.

Order of application: the file, then the variant's overrides (if a variant is chosen), then
``--set`` overrides, then ``--seed``. A variant is a table of quoted key paths (the ``--set``
syntax) to TOML values; a table value replaces the whole table. Loading a scenario validates
every variant it declares, so a bad variant fails before anything runs, with a key path such
as ``variants.wsc."nodes.1.params".x``. The resolved scenario of a variant is one run: it has
neither the ``variants`` nor the ``sweep`` table (the sweep belongs to the file, and may grid
over ``variant``).
"""

from __future__ import annotations

import copy
import difflib
import re
import tomllib
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, TypeAlias

from pydantic import ValidationError

from aquasim_py.scenario.errors import ScenarioError, format_key_path, raise_validation, show, toml_type
from aquasim_py.scenario.model import Loc, Scenario
from aquasim_py.scenario.schema import Scenario as _ScenarioModel
from aquasim_py.scenario.validate import check, check_sweep_size

__all__ = [
    "VARIANT_KEY",
    "Override",
    "Scenario",
    "apply_override",
    "load",
    "load_dict",
    "parse_key_path",
    "parse_value",
    "resolve",
    "variant_error",
]

#: the sweep grid key that selects a variant (``grid = { variant = ["a", "b"] }``)
VARIANT_KEY = "variant"

#: an override: ``"key.path=value"`` (value read as TOML) or a ``(key path, value)`` pair
Override: TypeAlias = "str | tuple[Sequence[str | int] | str, Any]"
Overrides: TypeAlias = "Sequence[Override] | Mapping[str, Any]"

_VARIANT_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_-]*")


# --------------------------------------------------------------------------- key paths
_TOKEN = re.compile(r"([^.\[\]]+)|\[(-?\d+)\]")


def parse_key_path(key: str) -> Loc:
    """``nodes.1.count`` or ``nodes[1].count`` -> ``["nodes", 1, "count"]``."""
    key = key.strip()
    if not key:
        raise ValueError("empty key path")
    if key.startswith(".") or key.endswith("."):
        raise ValueError(f"malformed key path {key!r}")
    out: Loc = []
    pos = 0
    while pos < len(key):
        if key[pos] == ".":
            pos += 1
            if pos >= len(key) or key[pos] in ".":
                raise ValueError(f"malformed key path {key!r}")
            continue
        m = _TOKEN.match(key, pos)
        if m is None:
            raise ValueError(f"malformed key path {key!r}")
        if m.group(2) is not None:
            out.append(int(m.group(2)))
        else:
            tok = m.group(1)
            out.append(int(tok) if tok.lstrip("-").isdigit() else tok)
        pos = m.end()
    return out


def parse_value(text: str) -> Any:
    """An override's value as TOML (``5``, ``1.5e3``, ``"x"``, ``[1, 2]``, ``{a = 1}``, ``true``);
    anything that is not valid TOML is taken as a plain string."""
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text


def apply_override(
    data: dict[str, Any], key: str | Sequence[str | int], value: Any, *, file: str | Path | None = None
) -> None:
    """Set ``data[key path] = value`` in place, creating missing tables on the way.

    Keys that the schema does not know are still set, so validation reports them as unknown.
    """
    loc = parse_key_path(key) if isinstance(key, str) else list(key)
    shown = format_key_path(loc)
    cur: Any = data
    for i, el in enumerate(loc):
        last = i == len(loc) - 1
        if isinstance(cur, list):
            if not isinstance(el, int):
                raise ScenarioError(file, shown, f"{format_key_path(loc[:i])} is a list: use an index, not {el!r}")
            if not -len(cur) <= el < len(cur):
                raise ScenarioError(file, shown, f"index {el} out of range ({len(cur)} entries)")
        elif isinstance(cur, dict):
            if isinstance(el, int):
                el = str(el)
                loc[i] = el
            if not last and el not in cur:
                cur[el] = {}
        else:
            raise ScenarioError(file, shown, f"cannot set a key inside {format_key_path(loc[:i])} (a {toml_type(cur)})")
        if last:
            cur[el] = value
        else:
            cur = cur[el]


def _parse_set(item: str, file: str | Path | None) -> tuple[Loc, Any]:
    if "=" not in item:
        raise ScenarioError(file, "--set", f"expected key.path=value (got {item!r})")
    key, text = item.split("=", 1)
    try:
        loc = parse_key_path(key)
    except ValueError as e:
        raise ScenarioError(file, "--set", str(e)) from None
    return loc, parse_value(text.strip())


def _parse_overrides(overrides: Overrides, file: Path | None) -> list[tuple[Loc, Any]]:
    items: Sequence[Any] = list(overrides.items()) if isinstance(overrides, Mapping) else overrides
    out: list[tuple[Loc, Any]] = []
    for item in items:
        if isinstance(item, str):
            out.append(_parse_set(item, file))
            continue
        key, value = item[0], item[1]
        if isinstance(key, str):
            try:
                loc = parse_key_path(key)
            except ValueError as e:
                raise ScenarioError(file, "--set", str(e)) from None
        else:
            loc = list(key)
        out.append((loc, value))
    return out


# --------------------------------------------------------------------------- loading
def _read(path: Path) -> dict[str, Any]:
    try:
        text = path.read_bytes().decode("utf-8")
    except FileNotFoundError:
        raise ScenarioError(path, "", "file not found") from None
    except IsADirectoryError:
        raise ScenarioError(path, "", "is a directory, not a scenario file") from None
    except PermissionError:
        raise ScenarioError(path, "", "permission denied") from None
    except UnicodeDecodeError as e:
        raise ScenarioError(path, "", f"not UTF-8 text ({e.reason} at byte {e.start})") from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        msg = str(e)
        m = re.search(r"\(at line (\d+), column (\d+)\)$", msg)
        if m:
            msg = msg[: m.start()].strip()
            raise ScenarioError(path, f"line {m.group(1)}, column {m.group(2)}", f"TOML syntax error: {msg}") from None
        raise ScenarioError(path, "", f"TOML syntax error: {msg}") from None


def load(
    path: str | Path, overrides: Overrides = (), seed: int | None = None, *, variant: str | None = None
) -> Scenario:
    """Read, override (``"key.path=value"`` strings) and validate a scenario file.

    ``variant``: resolve that ``[variants.NAME]`` table (None: the file as written; every
    declared variant is validated either way).
    """
    path = Path(path)
    raw = _read(path)
    return load_dict(raw, path, overrides=overrides, seed=seed, variant=variant)


def load_dict(
    raw: dict[str, Any],
    path: str | Path | None = None,
    overrides: Overrides = (),
    seed: int | None = None,
    *,
    variant: str | None = None,
) -> Scenario:
    """Validate scenario data (as parsed from TOML, or :meth:`Scenario.to_dict`).

    ``overrides``: ``"key.path=value"`` strings (value parsed as TOML), ``(key, value)`` pairs,
    or a mapping key path -> value; applied after the variant's own overrides. ``path`` is only
    used for messages and to resolve relative file names.
    """
    file = Path(path) if path is not None else None
    source = copy.deepcopy(raw)
    sets = _parse_overrides(overrides, file)
    for loc, _ in sets:
        if loc and loc[0] == "variants":
            raise ScenarioError(
                file,
                "--set",
                f"cannot change the [variants] tables ({format_key_path(loc)}): --set applies on top of "
                "every variant; choose one with --variant",
            )
    variants = _variant_overrides(source, file)
    if variant is not None:
        sc = _resolve_variant(source, file, variants, variant, sets, seed)
    else:
        sc = _validate(source, file, sets, seed)
        for name in variants:  # every variant must be runnable before anything runs
            _resolve_variant(source, file, variants, name, sets, seed)
        _check_sweep(sc, source, file, variants, sets, seed)
    sc._source = source
    sc._sets = sets
    sc._seed = seed
    return sc


def resolve(
    sc: Scenario, *, variant: str | None = None, overrides: Overrides = (), seed: int | None = None
) -> Scenario:
    """``sc`` re-resolved from its source with a variant, more overrides (applied after its own)
    or another seed. ``variant=None`` keeps ``sc``'s variant (if it is one)."""
    source = sc._source if sc._source is not None else sc.to_dict()
    more = _parse_overrides(overrides, sc.path)
    return load_dict(
        source,
        sc.path,
        overrides=[*sc._sets, *more],
        seed=seed if seed is not None else sc._seed,
        variant=variant if variant is not None else sc._variant,
    )


def _validate(
    data: dict[str, Any], file: Path | None, overrides: Sequence[tuple[Loc, Any]], seed: int | None
) -> Scenario:
    raw = copy.deepcopy(data)
    for loc, value in overrides:
        apply_override(raw, list(loc), value, file=file)
    if seed is not None:
        if not isinstance(raw.get("simulation"), dict):
            raw["simulation"] = {}
        raw["simulation"]["seed"] = seed
    try:
        sc = Scenario.model_validate(raw)
    except ValidationError as e:
        raise_validation(e, raw, file, model=_ScenarioModel)
    sc._path = file
    check(sc, file)
    return sc


# --------------------------------------------------------------------------- variants
VariantItems: TypeAlias = list[tuple[Loc, Any, str]]  # (key path, value, key as written)


def _variant_overrides(source: dict[str, Any], file: Path | None) -> dict[str, VariantItems]:
    """The ``[variants.NAME]`` tables as override lists, their names and keys checked."""
    table = source.get("variants")
    if table is None:
        return {}
    if not isinstance(table, dict):
        raise ScenarioError(file, "variants", f"expected [variants.NAME] tables (got {toml_type(table)} {show(table)})")
    out: dict[str, VariantItems] = {}
    for name, items in table.items():
        if not _VARIANT_NAME.fullmatch(name):
            raise ScenarioError(
                file, f'variants."{name}"', "a variant name is also a directory name: use letters, digits, _ and -"
            )
        if not isinstance(items, dict):
            raise ScenarioError(
                file,
                f"variants.{name}",
                f'expected a table of "key.path" = value overrides (got {toml_type(items)} {show(items)})',
            )
        parsed: VariantItems = []
        for key, value in items.items():
            shown = f'variants.{name}."{key}"'
            try:
                loc = parse_key_path(key)
            except ValueError as e:
                raise ScenarioError(file, shown, str(e)) from None
            if loc[0] in ("variants", "sweep"):
                raise ScenarioError(file, shown, f"a variant cannot change the [{loc[0]}] table")
            if [str(x) for x in loc[:2]] == ["simulation", "seed"]:
                raise ScenarioError(
                    file, shown, "every variant runs with the same seed: set simulation.seed (or --seed) instead"
                )
            parsed.append((loc, value, key))
        out[name] = parsed
    return out


def _unknown_variant(name: str, known: Sequence[str], file: Path | None, key: str = "variants") -> ScenarioError:
    if not known:
        return ScenarioError(file, key, f"no variant {name!r}: the scenario declares no [variants.NAME] tables")
    near = difflib.get_close_matches(name, known, n=1)
    hint = f"did you mean {near[0]!r}?" if near else f"declared: {', '.join(known)}"
    return ScenarioError(file, key, f"no variant {name!r} ({hint})")


def _resolve_variant(
    source: dict[str, Any],
    file: Path | None,
    variants: dict[str, VariantItems],
    name: str,
    sets: Sequence[tuple[Loc, Any]],
    seed: int | None,
) -> Scenario:
    if name not in variants:
        raise _unknown_variant(name, list(variants), file)
    items = variants[name]
    # one run: the variants and the sweep belong to the file, not to a variant of it
    base = {k: v for k, v in source.items() if k not in ("variants", "sweep")}
    try:
        sc = _validate(base, file, [*((loc, v) for loc, v, _ in items), *sets], seed)
    except ScenarioError as e:
        raise _in_variant(e, name, items, file) from None
    sc._variant = name
    return sc


def variant_error(sc: Scenario, e: ScenarioError) -> ScenarioError:
    """``e`` (found while building the variant ``sc``) re-keyed under the variant's key path."""
    if sc.variant is None or sc._source is None:
        return e
    items = _variant_overrides(sc._source, sc.path)[sc.variant]
    return _in_variant(e, sc.variant, items, sc.path)


def _in_variant(e: ScenarioError, name: str, items: VariantItems, file: Path | None) -> ScenarioError:
    """Re-key an error found in a variant: under the variant key it comes from, if any."""
    try:
        loc = [str(x) for x in parse_key_path(e.key_path)] if e.key_path else []
    except ValueError:
        loc = []
    best: tuple[Loc, Any, str] | None = None
    for item in items:
        vloc = [str(x) for x in item[0]]
        if loc[: len(vloc)] == vloc and (best is None or len(vloc) > len(best[0])):
            best = item
    if best is None and loc:
        # an error about a whole table (found by a constructor) inside which the variant set one key
        inside = [item for item in items if [str(x) for x in item[0]][: len(loc)] == loc]
        if len(inside) == 1:
            return ScenarioError(file, f'variants.{name}."{inside[0][2]}"', e.message)
    if best is None:
        inner = f"{e.key_path}: {e.message}" if e.key_path else e.message
        sets = {tuple(str(x) for x in item[0]) for item in items}
        if len(loc) >= 3 and loc[0] == "nodes" and loc[2] == "params":
            group = ("nodes", loc[1])
            if (*group, "protocol") in sets and (*group, "params") not in sets:
                inner += (
                    f' (this variant changes the protocol: give its parameters with "nodes.{loc[1]}.params" = {{...}})'
                )
        return ScenarioError(file, f"variants.{name}", inner)
    _, value, key = best
    n = len(best[0])
    rest = format_key_path(parse_key_path(e.key_path)[n:]) if len(loc) > n else ""
    suffix = "" if not rest else (rest if rest.startswith("[") else f".{rest}")
    msg = e.message
    if isinstance(value, dict) and "." not in key and not rest:
        msg += f' (to set one key write it quoted, e.g. "{key}.KEY" = value: a table value replaces the whole table)'
    return ScenarioError(file, f'variants.{name}."{key}"{suffix}', msg)


# --------------------------------------------------------------------------- sweep grid
def _check_sweep(
    sc: Scenario,
    source: dict[str, Any],
    file: Path | None,
    variants: dict[str, VariantItems],
    sets: Sequence[tuple[Loc, Any]],
    seed: int | None,
) -> None:
    """Sweep grid keys must name real scenario keys (or ``variant``) and every value must
    validate, in every swept variant."""
    if sc.sweep is None:
        return
    grid = sc.sweep.grid
    check_sweep_size(file, sc.sweep.runs, {k: len(v) for k, v in grid.items()})
    swept: list[str | None] = [None]
    if VARIANT_KEY in grid:
        swept = []
        for v in grid[VARIANT_KEY]:
            if not isinstance(v, str) or v not in variants:
                raise ScenarioError(
                    file,
                    f"sweep.grid.{VARIANT_KEY}",
                    _unknown_variant(str(v), list(variants), file).message,
                )
            swept.append(v)
    base = {k: v for k, v in source.items() if k not in ("sweep", "variants")}
    no_sweep = {k: v for k, v in source.items() if k != "sweep"}
    for key, values in grid.items():
        if key == VARIANT_KEY:
            continue
        shown = f'sweep.grid."{key}"'
        try:
            loc = parse_key_path(key)
        except ValueError as e:
            raise ScenarioError(file, shown, str(e)) from None
        if loc and loc[0] in ("sweep", "variants"):
            what = "its own settings" if loc[0] == "sweep" else f"the variants (grid over {VARIANT_KEY} instead)"
            raise ScenarioError(file, shown, f"a sweep cannot sweep {what}")
        if loc[:2] == ["simulation", "seed"]:
            raise ScenarioError(file, shown, "seeds are derived per run from simulation.seed: set sweep.runs instead")
        for v in values:
            for name in swept:
                try:
                    if name is None:
                        _validate(base, file, [*sets, (loc, v)], seed)
                    else:
                        _resolve_variant(no_sweep, file, variants, name, [*sets, (loc, v)], seed)
                except ScenarioError as e:
                    raise ScenarioError(file, shown, f"value {show(v)}: {e.key_path}: {e.message}") from None

"""TOML scenario -> validated :class:`Scenario` -> built :class:`~aquasim_py.kernel.Simulation`.

``load(path, overrides=[...], seed=None)`` reads the file with :mod:`tomllib`, applies
``--set key.path=value`` overrides, validates with the strict models of
:mod:`aquasim_py.scenario_schema`, then checks what needs several sections at once (positions
inside the volume, protocol parameters against the protocol's ``Params`` model, mobility
parameters against the mobility class, the sound-speed profile). Every user mistake raises
:class:`ScenarioError` naming the file, the key path (``nodes[1].count``) and the problem.

``build(sc)`` creates the simulation; per-node random draws (placement, clocks, mobility) come
from the simulation's named random streams, so one group's draws never shift another's.
"""

from __future__ import annotations

import copy
import csv
import difflib
import inspect
import math
import re
import tomllib
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import BaseModel, PrivateAttr, ValidationError

from aquasim_py import registry
from aquasim_py.scenario_schema import (
    ConstantSSP,
    CtdSSP,
    ExplicitPlacement,
    GridPlacement,
    IsogradientSSP,
    LayeredSSP,
    MunkSSP,
    NodeGroupSpec,
    UniformPlacement,
)
from aquasim_py.scenario_schema import Scenario as _ScenarioModel

__all__ = [
    "MOBILITY_CLASSES",
    "Scenario",
    "ScenarioError",
    "apply_override",
    "build",
    "format_key_path",
    "load",
    "load_dict",
    "make_ssp",
    "parse_key_path",
]

#: scenario mobility model name -> class name in aquasim_py.mobility
MOBILITY_CLASSES = {
    "static": "Static",
    "constant_velocity": "ConstantVelocity",
    "coordinated_turn": "CoordinatedTurn",
    "random_walk": "RandomWalk",
    "meandering_current": "MeanderingCurrent",
    "waypoints": "Waypoints",
}


class ScenarioError(Exception):
    """A mistake in a scenario (or its overrides): which file, which key, what is wrong."""

    def __init__(self, file: str | Path | None, key_path: str, message: str) -> None:
        self.file = str(file) if file is not None else "<scenario>"
        self.key_path = key_path
        self.message = message
        super().__init__(str(self))

    def __reduce__(self) -> tuple[Any, ...]:  # picklable across worker processes
        return (type(self), (self.file, self.key_path, self.message))

    def __str__(self) -> str:
        parts = [self.file]
        if self.key_path:
            parts.append(self.key_path)
        parts.append(self.message)
        return ": ".join(parts)


class Scenario(_ScenarioModel):
    """A validated scenario; remembers the file it came from (relative paths resolve there)."""

    _path: Path | None = PrivateAttr(default=None)
    _ctd: tuple[np.ndarray, np.ndarray, np.ndarray] | None = PrivateAttr(default=None)

    @property
    def path(self) -> Path | None:
        return self._path

    @property
    def name(self) -> str:
        return self._path.stem if self._path is not None else "scenario"

    def to_dict(self) -> dict[str, Any]:
        """The resolved scenario (defaults filled in) as plain JSON-able data; loads back as is."""
        return self.model_dump(mode="json", exclude_none=False)

    def protocols(self) -> list[type]:
        """The Node subclasses the groups use, in first-use order."""
        out: list[type] = []
        for g in self.nodes:
            cls = registry.get(g.protocol)
            if cls not in out:
                out.append(cls)
        return out


# --------------------------------------------------------------------------- key paths
_TOKEN = re.compile(r"([^.\[\]]+)|\[(-?\d+)\]")


def parse_key_path(key: str) -> list[str | int]:
    """``nodes.1.count`` or ``nodes[1].count`` -> ``["nodes", 1, "count"]``."""
    key = key.strip()
    if not key:
        raise ValueError("empty key path")
    if key.startswith(".") or key.endswith("."):
        raise ValueError(f"malformed key path {key!r}")
    out: list[str | int] = []
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


def format_key_path(loc: Iterable[str | int]) -> str:
    """``["nodes", 1, "count"]`` -> ``nodes[1].count``."""
    s = ""
    for el in loc:
        if isinstance(el, int):
            s += f"[{el}]"
        else:
            s += f".{el}" if s else str(el)
    return s


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
            raise ScenarioError(
                file, shown, f"cannot set a key inside {format_key_path(loc[:i])} (a {_toml_type(cur)})"
            )
        if last:
            cur[el] = value
        else:
            cur = cur[el]


def _parse_set(item: str, file: str | Path | None) -> tuple[list[str | int], Any]:
    if "=" not in item:
        raise ScenarioError(file, "--set", f"expected key.path=value (got {item!r})")
    key, text = item.split("=", 1)
    try:
        loc = parse_key_path(key)
    except ValueError as e:
        raise ScenarioError(file, "--set", str(e)) from None
    return loc, parse_value(text.strip())


# --------------------------------------------------------------------------- errors
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


def _toml_type(v: Any) -> str:
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


def _show(v: Any) -> str:
    if isinstance(v, float) and math.isnan(v):
        return "nan"
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (dict, list)):
        s = f"a {_toml_type(v)}"
        return s
    s = repr(v)
    return s if len(s) <= 60 else s[:57] + "..."


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


def _message(err: dict[str, Any], loc: list[str | int], model: type[BaseModel] | None) -> tuple[list[str | int], str]:
    typ = err["type"]
    ctx = err.get("ctx") or {}
    inp = err.get("input")
    if typ == "missing":
        if loc == ["nodes"]:
            return loc, "at least one node group is required (add a [[nodes]] table)"
        return loc, "required key missing"
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
        return loc, f"must be {op} {bound} (got {_show(inp)})"
    if typ == "finite_number":
        return loc, f"must be a finite number (got {_show(inp)})"
    if typ in _TYPE_WORDS:
        got = _show(inp)
        return loc, f"expected {_TYPE_WORDS[typ]} (got {_toml_type(inp)} {got})" if not isinstance(
            inp, (list, dict)
        ) else f"expected {_TYPE_WORDS[typ]} (got {got})"
    if typ == "literal_error":
        return loc, f"must be one of {ctx.get('expected')} (got {_show(inp)})"
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


def _raise_validation(
    exc: ValidationError, raw: Any, file: Any, prefix: Sequence[str | int] = (), model: type[BaseModel] | None = None
) -> None:
    err = exc.errors(include_url=False)[0]  # one line: the first problem is the one to fix
    loc = _clean_loc(list(err["loc"]), raw)
    loc, msg = _message(err, loc, model)
    raise ScenarioError(file, format_key_path(list(prefix) + loc), msg) from None


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


def load(path: str | Path, overrides: Sequence[str] = (), seed: int | None = None) -> Scenario:
    """Read, override (``"key.path=value"`` strings) and validate a scenario file."""
    path = Path(path)
    raw = _read(path)
    return load_dict(raw, path, overrides=overrides, seed=seed)


def load_dict(
    raw: dict[str, Any],
    path: str | Path | None = None,
    overrides: Sequence[str | tuple[Sequence[str | int] | str, Any]] = (),
    seed: int | None = None,
) -> Scenario:
    """Validate scenario data (as parsed from TOML, or :meth:`Scenario.to_dict`).

    ``overrides``: ``"key.path=value"`` strings (value parsed as TOML) or ``(key, value)`` pairs.
    ``path`` is only used for messages and to resolve relative file names.
    """
    file = Path(path) if path is not None else None
    raw = copy.deepcopy(raw)
    for item in overrides:
        if isinstance(item, str):
            loc, value = _parse_set(item, file)
        else:
            loc, value = item[0], item[1]
        apply_override(raw, loc, value, file=file)
    if seed is not None:
        if not isinstance(raw.get("simulation"), dict):
            raw["simulation"] = {}
        raw["simulation"]["seed"] = seed
    try:
        sc = Scenario.model_validate(raw)
    except ValidationError as e:
        _raise_validation(e, raw, file, model=_ScenarioModel)
    sc._path = file
    _check(sc, raw, file)
    return sc


def _check(sc: Scenario, raw: dict[str, Any], file: Path | None) -> None:
    """Checks across sections, with exact key paths."""
    # group names and counts
    seen: dict[str, int] = {}
    for i, g in enumerate(sc.nodes):
        if g.name is None:
            g.name = f"group{i}"
        if g.name in seen:
            raise ScenarioError(file, f"nodes[{i}].name", f"{g.name!r} is already the name of nodes[{seen[g.name]}]")
        seen[g.name] = i
        _check_count(g, i, file)
    # the sound-speed profile (its constructor knows the physics constraints)
    make_ssp(sc)
    vol = sc.environment.volume
    lo, hi = np.asarray(vol.lo), np.asarray(vol.hi)
    for i, g in enumerate(sc.nodes):
        p = g.placement
        if isinstance(p, ExplicitPlacement):
            for j, q in enumerate(p.positions):
                _inside(q, lo, hi, file, f"nodes[{i}].placement.positions[{j}]")
        elif isinstance(p, (UniformPlacement, GridPlacement)):
            for side in ("lo", "hi"):
                q = getattr(p, side)
                if q is not None:
                    _inside(q, lo, hi, file, f"nodes[{i}].placement.{side}")
            plo = np.asarray(p.lo if p.lo is not None else vol.lo)
            phi = np.asarray(p.hi if p.hi is not None else vol.hi)
            if np.any(plo > phi):
                raise ScenarioError(
                    file, f"nodes[{i}].placement", f"lo {plo.tolist()} is above hi {phi.tolist()} on some axis"
                )
        _check_protocol(g, i, raw, file)
        _check_mobility(g, i, file)
    # sweep grid keys must name real scenario keys and every value must validate
    if sc.sweep is not None:
        for key, values in sc.sweep.grid.items():
            try:
                loc = parse_key_path(key)
            except ValueError as e:
                raise ScenarioError(file, f'sweep.grid."{key}"', str(e)) from None
            if loc and loc[0] == "sweep":
                raise ScenarioError(file, f'sweep.grid."{key}"', "a sweep cannot sweep its own settings")
            if loc[:2] == ["simulation", "seed"]:
                raise ScenarioError(
                    file,
                    f'sweep.grid."{key}"',
                    "seeds are derived per run from simulation.seed: set sweep.runs instead",
                )
            base = {k: v for k, v in raw.items() if k != "sweep"}
            for v in values:
                try:
                    load_dict(base, file, overrides=[(loc, v)])
                except ScenarioError as e:
                    raise ScenarioError(
                        file, f'sweep.grid."{key}"', f"value {_show(v)}: {e.key_path}: {e.message}"
                    ) from None


def _check_count(g: NodeGroupSpec, i: int, file: Path | None) -> None:
    p = g.placement
    implied = None
    if isinstance(p, ExplicitPlacement):
        implied = len(p.positions)
    elif isinstance(p, GridPlacement):
        implied = int(np.prod(p.shape))
    if implied is None:
        if g.count is None:
            raise ScenarioError(file, f"nodes[{i}].count", "required key missing (a uniform placement needs a count)")
    elif g.count is None:
        g.count = implied
    elif g.count != implied:
        raise ScenarioError(
            file, f"nodes[{i}].count", f"{g.count} differs from the {p.kind} placement's {implied} positions"
        )


def _inside(q: Sequence[float], lo: np.ndarray, hi: np.ndarray, file: Path | None, key: str) -> None:
    q = np.asarray(q, dtype=float)
    if np.any(q < lo) or np.any(q > hi):
        raise ScenarioError(file, key, f"position {q.tolist()} is outside the volume lo={lo.tolist()} hi={hi.tolist()}")


def _check_finite(v: Any, loc: list[str | int], file: Path | None) -> None:
    """NaN / inf anywhere in free-form parameters (protocol, mobility) is a mistake."""
    if isinstance(v, float) and not math.isfinite(v):
        raise ScenarioError(file, format_key_path(loc), f"must be a finite number (got {_show(v)})")
    if isinstance(v, list):
        for j, x in enumerate(v):
            _check_finite(x, loc + [j], file)
    elif isinstance(v, dict):
        for k, x in v.items():
            _check_finite(x, loc + [k], file)


def _check_protocol(g: NodeGroupSpec, i: int, raw: dict[str, Any], file: Path | None) -> None:
    try:
        cls = registry.get(g.protocol)
    except registry.UnknownProtocolError as e:
        raise ScenarioError(file, f"nodes[{i}].protocol", e.message) from None
    _check_finite(g.params, ["nodes", i, "params"], file)
    Params = cls.Params
    fields = set(Params.model_fields)
    for k in g.params:
        if k not in fields:
            near = difflib.get_close_matches(k, sorted(fields), n=1)
            hint = (
                f" (did you mean {near[0]!r}?)"
                if near
                else (f" (allowed: {', '.join(sorted(fields))})" if fields else " (it takes none)")
            )
            raise ScenarioError(file, f"nodes[{i}].params.{k}", f"unknown parameter of protocol {g.protocol!r}{hint}")
    try:
        validated = Params.model_validate(g.params)
    except ValidationError as e:
        _raise_validation(e, g.params, file, prefix=("nodes", i, "params"), model=Params)
    # the resolved scenario carries every parameter, defaults included
    g.params = validated.model_dump(mode="json")


def _check_mobility(g: NodeGroupSpec, i: int, file: Path | None) -> None:
    try:
        cls = mobility_class(g.mobility.model)
    except ImportError:
        return  # mobility module not importable: build() will report it
    params = g.mobility.params()
    _check_finite(params, ["nodes", i, "mobility"], file)
    sig = inspect.signature(cls.__init__)
    accepted = [
        n
        for n, p in sig.parameters.items()
        if n not in ("self", "initial_positions", "box", "rng") and p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)
    ]
    if any(p.kind == p.VAR_KEYWORD for p in sig.parameters.values()):
        return
    for k in params:
        if k not in accepted:
            near = difflib.get_close_matches(k, accepted, n=1)
            hint = (
                f" (did you mean {near[0]!r}?)"
                if near
                else (f" (allowed: {', '.join(accepted)})" if accepted else " (it takes none)")
            )
            raise ScenarioError(
                file, f"nodes[{i}].mobility.{k}", f"unknown parameter of mobility model {g.mobility.model!r}{hint}"
            )


def mobility_class(model: str) -> type:
    from aquasim_py import mobility

    return getattr(mobility, MOBILITY_CLASSES[model])


# --------------------------------------------------------------------------- building
def _ctd_columns(spec: CtdSSP, file: Path | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    key = "environment.sound_speed.file"
    if spec.file is None:
        return (
            np.asarray(spec.depth_m, float),
            np.asarray(spec.temperature_c, float),
            np.asarray(spec.salinity_psu, float),
        )
    p = Path(spec.file)
    if not p.is_absolute() and file is not None:
        p = file.parent / p
    try:
        with open(p, newline="") as fh:
            rows = list(csv.DictReader(fh))
    except FileNotFoundError:
        raise ScenarioError(file, key, f"CTD file not found: {p}") from None
    except OSError as e:
        raise ScenarioError(file, key, f"cannot read CTD file {p}: {e.strerror}") from None
    names = {
        "depth": ("depth_m", "depth"),
        "temperature": ("temperature_c", "temperature"),
        "salinity": ("salinity_psu", "salinity"),
    }
    header = rows[0].keys() if rows else []
    cols = []
    for options in names.values():
        col = next((c for c in options if c in header), None)
        if col is None:
            raise ScenarioError(
                file, key, f"CTD file {p} has no {options[0]} column (columns: depth_m, temperature_c, salinity_psu)"
            )
        try:
            cols.append(np.array([float(r[col]) for r in rows]))
        except (TypeError, ValueError):
            raise ScenarioError(file, key, f"CTD file {p}: column {col} has a non-numeric value") from None
    return cols[0], cols[1], cols[2]


def make_ssp(sc: Scenario) -> Any:
    """The scenario's sound-speed profile object (aquasim_py.channel.ssp)."""
    from aquasim_py.channel import ssp

    spec = sc.environment.sound_speed
    bottom = sc.environment.bottom_m
    try:
        if isinstance(spec, ConstantSSP):
            return ssp.Constant(spec.speed_mps, bottom=bottom)
        if isinstance(spec, IsogradientSSP):
            return ssp.Isogradient(spec.surface_speed_mps, spec.gradient_per_s, bottom=bottom)
        if isinstance(spec, LayeredSSP):
            return ssp.Layered(np.asarray(spec.depths_m), np.asarray(spec.speeds_mps), bottom=bottom)
        if isinstance(spec, MunkSSP):
            return ssp.Munk(
                spec.axis_depth_m,
                spec.axis_speed_mps,
                spec.epsilon,
                spec.scale_m,
                bottom=bottom,
                n_layers=spec.n_layers,
            )
        if isinstance(spec, CtdSSP):
            if sc._ctd is None:
                sc._ctd = _ctd_columns(spec, sc.path)
            return ssp.from_ctd(*sc._ctd, bottom=bottom)
    except ValueError as e:
        raise ScenarioError(sc.path, "environment.sound_speed", str(e)) from None
    raise AssertionError(f"unhandled profile {spec!r}")


def placement_positions(
    g: NodeGroupSpec, volume_lo: Sequence[float], volume_hi: Sequence[float], rng: np.random.Generator
) -> np.ndarray:
    """Initial positions (count, 3) of a group (m).

    uniform: i.i.d. uniform in the placement box (default the volume), drawn from ``rng``;
    grid: ``shape`` points per axis from lo to hi inclusive (one point: the middle), the last
    axis varying fastest; explicit: as given.
    """
    p = g.placement
    if isinstance(p, ExplicitPlacement):
        return np.asarray(p.positions, dtype=float).reshape(-1, 3)
    lo = np.asarray(p.lo if p.lo is not None else volume_lo, dtype=float)
    hi = np.asarray(p.hi if p.hi is not None else volume_hi, dtype=float)
    if isinstance(p, UniformPlacement):
        assert g.count is not None
        return rng.uniform(lo, hi, size=(g.count, 3))
    axes = [np.linspace(lo[k], hi[k], n) if n > 1 else np.array([(lo[k] + hi[k]) / 2.0]) for k, n in enumerate(p.shape)]
    return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)


def _clock_factory(spec: Any) -> Any:
    """``(node_id, rng) -> Clock`` drawing this node's skew and offset from its own stream."""
    from aquasim_py.clock import Clock

    def make(node_id: int, rng: np.random.Generator) -> Clock:
        skew = (spec.skew_ppm + spec.skew_std_ppm * rng.standard_normal()) * 1e-6
        offset = spec.offset_s + spec.offset_std_s * rng.standard_normal()
        needs_rng = spec.drift_std_ppm > 0.0 or spec.jitter_std_s > 0.0
        return Clock(
            skew=float(skew),
            offset=float(offset),
            drift_std=spec.drift_std_ppm * 1e-6,
            drift_interval=spec.drift_interval_s,
            jitter_std=spec.jitter_std_s,
            rng=rng if needs_rng else None,
        )

    return make


def channel_config(sc: Scenario) -> Any:
    """The kernel's ChannelConfig for the scenario's [channel] table."""
    from aquasim_py.channel.acoustic import ChannelConfig

    c = sc.channel
    return ChannelConfig(
        max_range_m=c.max_range_m,
        bitrate_bps=c.bitrate_bps,
        source_level_db=c.source_level_db,
        frequency_khz=c.frequency_khz,
        bandwidth_khz=c.bandwidth_khz,
        spreading=c.spreading,
        shipping=c.noise.shipping,
        wind_mps=c.noise.wind_mps,
        snr_threshold_db=c.snr_threshold_db,
        collision=c.collision,
        capture_threshold_db=c.capture_threshold_db,
        jitter_std_s=c.jitter_std_s,
        reflections=c.reflections,
        sound_speed_std_mps=c.sound_speed_std_mps,
        sound_speed_corr_s=c.sound_speed_corr_s,
    )


def build(sc: Scenario) -> Any:
    """A ready-to-run :class:`~aquasim_py.kernel.Simulation` for a validated scenario.

    Random draws per group come from the simulation's streams keyed by the group's name:
    ("group", name, "placement") for uniform positions, ("group", name, "mobility") for the
    mobility model, ("node", id, "clock") for each node's clock. Errors that only the physics
    constructors detect (e.g. a mobility parameter out of range) become ScenarioError.
    """
    from aquasim_py.channel.acoustic import no_snr
    from aquasim_py.kernel import Simulation
    from aquasim_py.mobility import Box
    from aquasim_py.node import Sensors
    from aquasim_py.trace import TraceConfig

    file = sc.path
    vol = sc.environment.volume
    box = Box(vol.lo, vol.hi)
    try:
        cfg = channel_config(sc)
    except ValueError as e:
        raise ScenarioError(file, "channel", str(e)) from None
    sim = Simulation(
        sc.simulation.seed,
        make_ssp(sc),
        box,
        cfg,
        TraceConfig(position_interval=sc.trace.position_interval_s),
        loss_model=no_snr if sc.channel.loss_model == "none" else None,
    )
    for i, g in enumerate(sc.nodes):
        assert g.name is not None and g.count is not None
        cls = registry.get(g.protocol)
        pos = placement_positions(g, vol.lo, vol.hi, sim.rng("group", g.name, "placement"))
        try:
            mob_cls = mobility_class(g.mobility.model)
        except (ImportError, AttributeError) as e:
            raise ScenarioError(file, f"nodes[{i}].mobility.model", f"mobility model unavailable ({e})") from None
        try:
            # the same stream add_group would hand a mobility factory
            mobility = mob_cls(pos, box, sim.rng("group", g.name, "mobility"), **g.mobility.params())
        except (ValueError, TypeError) as e:
            raise ScenarioError(file, f"nodes[{i}].mobility", str(e)) from None
        s = g.sensors
        sim.add_group(
            cls,
            g.count,
            role=g.role,
            mobility=mobility,
            clocks=_clock_factory(g.clock),
            params=g.params,
            name=g.name,
            sensors=Sensors(
                depth_std=s.depth_noise_std_m,
                velocity_std=s.velocity_noise_std_mps,
                velocity=s.velocity_sensor,
                position_std=s.position_noise_std_m,
                position=s.position_fix,
            ),
        )
    return sim

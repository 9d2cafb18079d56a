"""Checks of a scenario across sections, with exact key paths: group names and counts, the
sound-speed profile, positions inside the volume, protocol parameters against the protocol's
``Params`` model, mobility parameters against the mobility class."""

from __future__ import annotations

import difflib
import inspect
import math
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from pydantic import BaseModel, ValidationError

from aquasim_py import registry
from aquasim_py.scenario.build import make_ssp, mobility_class, warn_deprecated_mobility
from aquasim_py.scenario.errors import ScenarioError, format_key_path, raise_validation, show
from aquasim_py.scenario.schema import ExplicitPlacement, GridPlacement, NodeGroupSpec, UniformPlacement

if TYPE_CHECKING:
    from aquasim_py.scenario.load import Scenario

__all__ = ["check"]


def check(sc: Scenario, file: Path | None) -> None:
    """Checks across sections (fills in group names, implied counts, validated protocol params)."""
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
        _check_protocol(g, i, file)
        _check_mobility(g, i, file)


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
    pt = np.asarray(q, dtype=float)
    if np.any(pt < lo) or np.any(pt > hi):
        raise ScenarioError(
            file, key, f"position {pt.tolist()} is outside the volume lo={lo.tolist()} hi={hi.tolist()}"
        )


def _check_finite(v: Any, loc: list[str | int], file: Path | None) -> None:
    """NaN / inf anywhere in free-form parameters (protocol, mobility) is a mistake."""
    if isinstance(v, float) and not math.isfinite(v):
        raise ScenarioError(file, format_key_path(loc), f"must be a finite number (got {show(v)})")
    if isinstance(v, list):
        for j, x in enumerate(v):
            _check_finite(x, loc + [j], file)
    elif isinstance(v, dict):
        for k, x in v.items():
            _check_finite(x, loc + [k], file)


def _check_protocol(g: NodeGroupSpec, i: int, file: Path | None) -> None:
    try:
        cls = registry.get(g.protocol)
    except registry.UnknownProtocolError as e:
        raise ScenarioError(file, f"nodes[{i}].protocol", e.message) from None
    _check_finite(g.params, ["nodes", i, "params"], file)
    Params: type[BaseModel] = cls.Params  # type: ignore[attr-defined]  # every registered Node has one
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
        raise_validation(e, g.params, file, prefix=("nodes", i, "params"), model=Params)
    # the resolved scenario carries every parameter, defaults included
    g.params = validated.model_dump(mode="json")


def _check_mobility(g: NodeGroupSpec, i: int, file: Path | None) -> None:
    warn_deprecated_mobility(g.mobility.model, file)
    try:
        cls = mobility_class(g.mobility.model)
    except ImportError:
        return  # mobility module not importable: build() will report it
    params = g.mobility.params()
    _check_finite(params, ["nodes", i, "mobility"], file)
    sig = inspect.signature(cls)  # the constructor's parameters, without self
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

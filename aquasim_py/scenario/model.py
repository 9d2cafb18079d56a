"""The validated :class:`Scenario`: the file format's model plus where it came from.

Its own module so that loading (:mod:`~aquasim_py.scenario.load`), the cross-section checks
(:mod:`~aquasim_py.scenario.validate`) and building (:mod:`~aquasim_py.scenario.build`) all
import it from below, none of them from another (no import cycle).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, TypeAlias

import numpy as np
from pydantic import PrivateAttr

from aquasim_py import registry
from aquasim_py.scenario.ocean import ARRIVAL_KEYS, range_dependent
from aquasim_py.scenario.schema import PHY_KEYS
from aquasim_py.scenario.schema import Scenario as _ScenarioModel

__all__ = ["Loc", "Scenario"]

#: a key path as a list: ``["nodes", 1, "count"]``
Loc: TypeAlias = list[str | int]


class Scenario(_ScenarioModel):
    """A validated scenario; remembers the file it came from (relative paths resolve there),
    the data and overrides it was resolved from, and the variant it is (if any)."""

    _path: Path | None = PrivateAttr(default=None)
    _ctd: tuple[np.ndarray, np.ndarray, np.ndarray] | None = PrivateAttr(default=None)
    _source: dict[str, Any] | None = PrivateAttr(default=None)
    _sets: list[tuple[Loc, Any]] = PrivateAttr(default_factory=list)
    _seed: int | None = PrivateAttr(default=None)
    _variant: str | None = PrivateAttr(default=None)

    @property
    def path(self) -> Path | None:
        return self._path

    @property
    def base_dir(self) -> Path | None:
        """The directory the scenario's relative file names (a plug-in's ``./file.py``) start
        from: its file's directory; None without a file (then the current directory)."""
        return self._path.parent if self._path is not None else None

    @property
    def name(self) -> str:
        return self._path.stem if self._path is not None else "scenario"

    @property
    def variant(self) -> str | None:
        """The variant this scenario is the resolution of; None for the file as written."""
        return self._variant

    @property
    def variant_names(self) -> list[str]:
        """The declared variants, in file order (empty when the file declares none)."""
        return list(self.variants or {})

    @property
    def declared_variants(self) -> list[str]:
        """The variants of the file this scenario was resolved from (also for a variant)."""
        source = self._source if self._source is not None else self.to_dict()
        table = source.get("variants")
        return list(table) if isinstance(table, dict) else []

    def to_dict(self) -> dict[str, Any]:
        """The resolved scenario (defaults filled in) as plain JSON-able data; loads back as is."""
        d = self.model_dump(mode="json", exclude_none=False)
        if d.get("variants") is None:
            d.pop("variants", None)  # a file without variants resolves exactly as before they existed
        unset = [] if range_dependent(self) else list(ARRIVAL_KEYS)  # the arrival keys do nothing there
        for key in unset + list(PHY_KEYS):  # unset, as before they existed
            if key not in self.channel.model_fields_set:
                d["channel"].pop(key, None)
        return d

    def protocols(self) -> list[type]:
        """The Node subclasses the groups use, in first-use order."""
        out: list[type] = []
        for g in self.nodes:
            cls = registry.get(g.protocol, base=self.base_dir)
            if cls not in out:
                out.append(cls)
        return out

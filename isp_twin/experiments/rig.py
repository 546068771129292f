"""Rig files: every setting of the real rig that the paper leaves unstated, with its provenance.

A rig file (``models/rigs/<name>.yaml``, the paper's rig is ``paper_rig``)
holds one *knob* per unstated setting: its value and unit, the scenario keys
it sets, a plausible range, and where the value comes from (the paper, an
assumption made before any closed-loop result, or a calibration, naming the
paper cells whose results shaped it). A scenario names its rig (key `rig`);
the rig's values fill every scenario key the scenario does not set itself.
`isp-twin calibrate` refits the knobs that carry a `fit` block on the cells
it names, and labels every paper cell as fitted, shaped or validation.

The file format is described in the header of ``models/rigs/paper_rig.yaml``.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Any, Literal

from isp_twin.errors import ResourceNotFound, RigError, ScenarioError, nearest
from isp_twin.experiments.paper import PAPER_CELLS

__all__ = [
    "DEFAULT_RIG",
    "PROVENANCES",
    "KnobFit",
    "Knob",
    "Rig",
    "load_rig",
    "parse_rig",
    "resolve_rig",
]

#: The rig a scenario uses when it names none.
DEFAULT_RIG = "paper_rig"
#: Where a knob's value comes from.
PROVENANCES: tuple[str, ...] = ("paper", "assumption", "calibrated")

_TOP_KEYS = ("name", "description", "knobs")
_KNOB_KEYS = (
    "value",
    "unit",
    "keys",
    "when",
    "range",
    "choices",
    "provenance",
    "cells",
    "fit",
    "note",
)
_REQUIRED = ("value", "unit", "keys", "provenance", "note")
_FIT_KEYS = ("cells", "values")


@dataclass(frozen=True)
class KnobFit:
    """What `isp-twin calibrate` fits for one knob.

    Attributes:
        cells: the paper cells whose error it minimises (PAPER_CELLS names).
        values: the candidate values scanned, in the knob's unit.
    """

    cells: tuple[str, ...]
    values: tuple[float, ...]


@dataclass(frozen=True)
class Knob:
    """One unstated setting of the rig.

    Attributes:
        name: the knob's name in the file.
        value: its value, in `unit` (a number, or a name for `choices` knobs).
        unit: the unit (paper units: deg, deg/s, digits, counts).
        keys: the scenario key paths it sets.
        when: scenario key path -> value: the knob applies only where all match.
        range: plausible (low, high) in `unit`, or None for a named setting.
        choices: the allowed names of a named setting, or None.
        provenance: one of `PROVENANCES`.
        cells: the paper cells whose results shaped the value (calibrated knobs).
        fit: what `isp-twin calibrate` fits, or None (paper, assumption, or
            chosen by hand).
        note: why this value.
    """

    name: str
    value: Any
    unit: str
    keys: tuple[str, ...]
    when: Mapping[str, Any] = field(default_factory=dict)
    range: tuple[float, float] | None = None
    choices: tuple[str, ...] | None = None
    provenance: Literal["paper", "assumption", "calibrated"] = "assumption"
    cells: tuple[str, ...] = ()
    fit: KnobFit | None = None
    note: str = ""


@dataclass(frozen=True)
class Rig:
    """A rig file, checked.

    Attributes:
        name: the rig's name.
        description: what rig it describes.
        knobs: name -> `Knob`, in file order.
        path: the file (None when built in code).
        text: the file's text, as read.
    """

    name: str
    description: str
    knobs: Mapping[str, Knob]
    path: Path | None = None
    text: str = field(default="", repr=False)

    def knob(self, name: str) -> Knob:
        """The knob called `name`.

        Raises:
            RigError: no such knob (names the nearest and the available ones).
        """
        try:
            return self.knobs[name]
        except KeyError:
            raise RigError(
                f"{self.path or self.name}: no knob '{name}'{nearest(name, self.knobs)}; "
                f"knobs: {', '.join(self.knobs)}"
            ) from None

    def fitted(self) -> tuple[Knob, ...]:
        """The knobs `isp-twin calibrate` fits (those with a `fit` block)."""
        return tuple(k for k in self.knobs.values() if k.fit is not None)

    def fitted_cells(self) -> tuple[str, ...]:
        """The paper cells some knob is fitted on, in PAPER_CELLS order."""
        used = {c for k in self.fitted() for c in k.fit.cells}
        return tuple(c for c in PAPER_CELLS if c in used)

    def shaping(self, cell: str) -> tuple[str, ...]:
        """The calibrated knobs whose choice the results of `cell` shaped."""
        return tuple(k.name for k in self.knobs.values() if cell in k.cells)

    def applies(self, knob: Knob, scenario: Any) -> bool:
        """Whether `knob` applies to `scenario` (its `when` conditions all hold)."""
        return all(_get(scenario, key) == value for key, value in knob.when.items())

    def settings(self, scenario: Any) -> dict[str, Any]:
        """Scenario key path -> value of every knob that applies to `scenario`."""
        out = {}
        for knob in self.knobs.values():
            if self.applies(knob, scenario):
                for key in knob.keys:
                    out[key] = knob.value
        return out

    def fill(self, raw: Mapping[str, Any], scenario: Any) -> dict[str, Any]:
        """`raw` (a scenario mapping) with the rig's values added where it sets none.

        Args:
            raw: the scenario file's mapping (checked: every level a mapping).
            scenario: the scenario built from `raw` alone, for `when`.
        """
        out = _copy(raw)
        for key, value in self.settings(scenario).items():
            *parents, leaf = key.split(".")
            node = out
            for part in parents:
                node = node.setdefault(part, {})
            node.setdefault(leaf, value)
        return out


def _copy(raw: Mapping[str, Any]) -> dict[str, Any]:
    return {k: _copy(v) if isinstance(v, Mapping) else v for k, v in raw.items()}


def _get(obj: Any, key: str) -> Any:
    for part in key.split("."):
        obj = getattr(obj, part)
    return obj


# ---------------------------------------------------------------- loading


def resolve_rig(value: str, source: Path | None = None) -> Path:
    """The rig file named by a scenario's `rig` key.

    Args:
        value: a path (relative to the scenario's folder), or a shipped name
            under models/rigs (``paper_rig``).
        source: the scenario file, or None.

    Raises:
        ResourceNotFound: no such file (lists the shipped rigs).
    """
    from isp_twin.resources import resource_root

    shipped = resource_root() / "models" / "rigs"
    path = Path(value)
    candidates = []
    if source is not None and not path.is_absolute():
        candidates.append(source.parent / path)
    candidates.append(path)
    if path.name == value:
        candidates += [shipped / value, shipped / f"{value}.yaml"]
    for c in candidates:
        if c.exists():  # a folder or unreadable file: the loader names what is wrong
            return c
    available = sorted(p.stem for p in shipped.glob("*.yaml"))
    raise ResourceNotFound(
        f"{source or 'scenario'}: rig: file '{value}' not found; shipped: {', '.join(available)}"
    )


def load_rig(path: str | Path) -> Rig:
    """Load and check a rig file (cached per file version).

    Raises:
        ResourceNotFound: no such file.
        RigError: unreadable, invalid YAML, unknown key, missing key, bad
            value, value outside its range, unknown cell; the message names
            the file and the knob.
    """
    path = Path(path)
    try:
        stat = os.stat(path)
        version = (stat.st_mtime_ns, stat.st_size)
    except OSError:
        version = (0, 0)  # read_text names the problem
    return _load_rig(str(path), version)


@lru_cache(maxsize=16)
def _load_rig(path: str, version: tuple[int, int]) -> Rig:
    from isp_twin.input_files import load_yaml

    raw, text = load_yaml(path, "rig file", RigError)
    return parse_rig(raw, Path(path), text)


def _unknown(where: str, key: Any, allowed: tuple[str, ...]) -> RigError:
    return RigError(
        f"{where}{key}: unknown key{nearest(str(key), allowed)}; allowed: {', '.join(allowed)}"
    )


def _fields(raw: Any, where: str, allowed: tuple[str, ...], required: tuple[str, ...], what: str):
    """Check that `raw` is a mapping with only `allowed` keys and every `required` one."""
    if not isinstance(raw, Mapping):
        raise RigError(f"{where}: expected {what}, got {raw!r}")
    for key in raw:
        if key not in allowed:
            raise _unknown(f"{where}.", key, allowed)
    for key in required:
        if key not in raw:
            raise RigError(f"{where}: missing key '{key}' (required: {', '.join(required)})")


def _number(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise RigError(f"{where}: expected a finite number, got {value!r}")
    return float(value)


def _names(value: Any, where: str) -> tuple[str, ...]:
    if not isinstance(value, list) or not value or not all(isinstance(v, str) for v in value):
        raise RigError(f"{where}: expected a non-empty list of names, got {value!r}")
    return tuple(value)


def _cells(value: Any, where: str) -> tuple[str, ...]:
    cells = _names(value, where)
    for c in cells:
        if c not in PAPER_CELLS:
            raise RigError(
                f"{where}: unknown paper cell '{c}'{nearest(c, PAPER_CELLS)}; "
                f"cells: {', '.join(PAPER_CELLS)}"
            )
    return cells


def _parse_knob(name: str, raw: Any, where: str) -> Knob:
    _fields(raw, where, _KNOB_KEYS, _REQUIRED, "a mapping of keys")
    if ("range" in raw) == ("choices" in raw):
        raise RigError(f"{where}: give either 'range' (a number) or 'choices' (a name)")
    for key in ("unit", "note"):
        if not isinstance(raw[key], str):
            raise RigError(f"{where}.{key}: expected text, got {raw[key]!r}")
    keys = _names(raw["keys"], f"{where}.keys")
    value, when = _checked_value_and_when(raw, keys, where)
    span = choices = None
    if "range" in raw:
        span = _checked_range(raw["range"], value, where)
    else:
        choices = _names(raw["choices"], f"{where}.choices")
        if value not in choices:
            raise RigError(f"{where}.value: {value!r} is not one of its choices {list(choices)}")
    provenance, cells = _checked_provenance(raw, where)
    fit = None
    if "fit" in raw:
        fit = _parse_fit(raw["fit"], f"{where}.fit", keys, cells, span)
    return Knob(
        name=name,
        value=value,
        unit=raw["unit"],
        keys=keys,
        when=when,
        range=span,
        choices=choices,
        provenance=provenance,
        cells=cells,
        fit=fit,
        note=raw["note"],
    )


def _checked_value_and_when(raw: Mapping, keys: tuple[str, ...], where: str) -> tuple[Any, dict]:
    """The knob's value, checked as each scenario key it sets, and its `when` conditions."""
    from isp_twin.experiments.scenario import check_scenario_value

    value = raw["value"]
    try:
        for key in keys:
            value = check_scenario_value(key, raw["value"], f"{where}.value (scenario key {key})")
    except ScenarioError as exc:
        raise RigError(str(exc)) from None
    when = raw.get("when", {})
    if not isinstance(when, Mapping):
        raise RigError(f"{where}.when: expected a mapping of scenario keys, got {when!r}")
    try:
        when = {k: check_scenario_value(str(k), v, f"{where}.when.{k}") for k, v in when.items()}
    except ScenarioError as exc:
        raise RigError(str(exc)) from None
    return value, when


def _checked_range(r: Any, value: Any, where: str) -> tuple[float, float]:
    """A numeric knob's plausible range [low, high], its value inside it."""
    if not isinstance(r, list) or len(r) != 2:
        raise RigError(f"{where}.range: expected [low, high], got {r!r}")
    span = (_number(r[0], f"{where}.range"), _number(r[1], f"{where}.range"))
    if span[0] > span[1]:
        raise RigError(f"{where}.range: low {span[0]:g} is above high {span[1]:g}")
    v = _number(value, f"{where}.value")
    if not span[0] <= v <= span[1]:
        raise RigError(
            f"{where}.value: {v:g} lies outside its plausible range [{span[0]:g}, {span[1]:g}]"
        )
    return span


def _checked_provenance(raw: Mapping, where: str) -> tuple[str, tuple[str, ...]]:
    """The knob's provenance, and the paper cells that shaped it (calibrated knobs only)."""
    provenance = raw["provenance"]
    if provenance not in PROVENANCES:
        raise RigError(
            f"{where}.provenance: {provenance!r} is not one of {', '.join(PROVENANCES)}"
            f"{nearest(str(provenance), PROVENANCES)}"
        )
    cells: tuple[str, ...] = ()
    if provenance == "calibrated":
        if "cells" not in raw:
            raise RigError(
                f"{where}.cells: a calibrated knob names the paper cells whose results shaped it"
            )
        cells = _cells(raw["cells"], f"{where}.cells")
    elif "cells" in raw or "fit" in raw:
        key = "cells" if "cells" in raw else "fit"
        raise RigError(
            f"{where}.{key}: only a calibrated knob has {key} (provenance: {provenance})"
        )
    return provenance, cells


def _parse_fit(raw: Any, where: str, keys, cells, span) -> KnobFit:
    from isp_twin.experiments.scenario import check_scenario_value

    _fields(raw, where, _FIT_KEYS, _FIT_KEYS, "a mapping with cells and values")
    if span is None:
        raise RigError(f"{where}: only a numeric knob (with a range) can be fitted")
    fit_cells = _cells(raw["cells"], f"{where}.cells")
    for c in fit_cells:
        if c not in cells:
            raise RigError(f"{where}.cells: '{c}' is fitted on but not listed in the knob's cells")
    values = raw["values"]
    if not isinstance(values, list) or not values:
        raise RigError(f"{where}.values: expected a non-empty list of numbers, got {values!r}")
    out = []
    for i, v in enumerate(values):
        x = _number(v, f"{where}.values[{i}]")
        if not span[0] <= x <= span[1]:
            raise RigError(
                f"{where}.values[{i}]: {x:g} lies outside the range [{span[0]:g}, {span[1]:g}]"
            )
        try:
            for key in keys:
                check_scenario_value(key, v, f"{where}.values[{i}] (scenario key {key})")
        except ScenarioError as exc:
            raise RigError(str(exc)) from None
        out.append(x)
    return KnobFit(cells=fit_cells, values=tuple(out))


def parse_rig(raw: Any, source: str | Path = "<rig>", text: str = "") -> Rig:
    """Build a `Rig` from parsed YAML; errors name `source` and the knob."""
    if not isinstance(raw, Mapping):
        raise RigError(f"{source}: expected a mapping with {', '.join(_TOP_KEYS)}, got {raw!r}")
    for key in raw:
        if key not in _TOP_KEYS:
            raise _unknown(f"{source}: ", key, _TOP_KEYS)
    name = raw.get("name", Path(str(source)).stem)
    description = raw.get("description", "")
    for key, value in (("name", name), ("description", description)):
        if not isinstance(value, str):
            raise RigError(f"{source}: {key}: expected text, got {value!r}")
    knobs_raw = raw.get("knobs")
    if not isinstance(knobs_raw, Mapping) or not knobs_raw:
        raise RigError(f"{source}: knobs: expected a mapping of knob names to knobs")
    knobs: dict[str, Knob] = {}
    owner: dict[str, str] = {}
    for kname, kraw in knobs_raw.items():
        knob = _parse_knob(str(kname), kraw, f"{source}: knobs.{kname}")
        for key in knob.keys:
            if key in owner:
                raise RigError(
                    f"{source}: knobs.{kname}.keys: '{key}' is also set by knob '{owner[key]}'"
                )
            owner[key] = str(kname)
        knobs[str(kname)] = knob
    path = Path(source) if not str(source).startswith("<") else None
    return Rig(name=name, description=description, knobs=knobs, path=path, text=text)

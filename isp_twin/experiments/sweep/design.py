"""Sweep files: the design of many closed-loop runs, checked whole, expanded into runs.

A sweep file (YAML) names a base scenario and what to vary; every key is
optional except `scenario`::

    name: gamma_kp                  # default: the file's stem
    scenario: turbulence_1_6Hz      # shipped name, or a path relative to this file
    parameters: paper_table2        # the plant's parameter file (default: the scenario's)
    axis: inner_az                  # the inner axis whose J (Eq. 10) is the objective
    seeds: {first: 1, count: 10}    # or a list [1, 2, 3] (default: the scenario's seed)
    cases:                          # a list of settings, each of several keys
      - {label: PI, controller.inner_az.nfc.enabled: false}
      - {label: PI+NFC, controller.inner_az.nfc.enabled: true}
    grid:                           # every combination of these values
      controller.inner_az.nfc.gamma: [0.90, 0.95, 0.98]
      controller.inner_az.pi_nfc.kp_digit_per_count: {from: 2.0, to: 4.0, num: 5}
    random:                         # uniform draws
      count: 20
      seed: 7
      knobs:
        follower.kp_digit_per_deg: {low: 1000.0, high: 3000.0}
    uncertainty:                    # plant parameters drawn from the file's ci95
      draws: 5
      seed: 11

Knobs are dotted scenario key paths, checked against the scenario schema
(type, range) with the sweep file's key path in the message. The runs are
cases x grid x random draws x parameter draws x seeds; runs whose inputs
are identical (two random draws of an integer knob that agree) are one run.

Parameter uncertainty: draw d perturbs every parameter that has a ci95 in
the file by a normal deviate of standard deviation ci95/1.96 (the ci95 is
the half-width of a normal 95 % interval), the pole kept inside (0, 1) and
the others positive. Only the plant (the twin) gets the drawn set; the NFC
keeps compensating with the scenario's `nfc_parameters` (the identified model
by default; 'plant': the file's nominal values), as on hardware the
controller holds the identified model while the plant differs from it.

Each run's identity is the SHA-256 of its inputs (the full scenario with
every default, the parameter file's text, the NFC model file's text, the
drawn values, the seed and the package version): `RunSpec.key`, the results store's key.
"""

from __future__ import annotations

import dataclasses
import hashlib
import itertools
import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from isp_twin import __version__
from isp_twin.errors import IspTwinError, ResourceNotFound, ScenarioError, nearest
from isp_twin.experiments.scenario import (
    Scenario,
    check_scenario_value,
    load_scenario,
    parse_scenario,
    resolve_parameters,
    scenario_to_raw,
)
from isp_twin.model.parameters import PAPER_FIELDS
from isp_twin.vocabulary import INNER_AXES, REGIMES

__all__ = [
    "RunSpec",
    "Sweep",
    "load_sweep",
    "parse_sweep",
    "make_run",
    "draw_parameters",
]

_TOP_KEYS = (
    "name",
    "description",
    "scenario",
    "parameters",
    "axis",
    "seeds",
    "cases",
    "grid",
    "random",
    "uncertainty",
)
#: At most this many runs in one sweep file (a typo in `num` should not queue a billion).
MAX_RUNS = 1_000_000


@dataclass(frozen=True)
class RunSpec:
    """Everything one run needs, picklable and JSON-ready (a worker rebuilds the run from it).

    Attributes:
        key: SHA-256 hex of the inputs (the store's key).
        index: position in the design.
        scenario_raw: the full scenario as a mapping (every key, knobs applied).
        scenario_source: the base scenario file (resolves relative paths), or None.
        parameters: path of the plant's parameter file.
        parameter_draw: drawn values, axis -> regime -> field -> value in the
            file's units, or None for the nominal set.
        seed: noise seed.
        knobs: what this run varies: knob key path -> value, plus ``label``
            (a case) and ``draw`` (the parameter draw) where present.
        axis: the inner axis whose J is the objective.
    """

    key: str
    index: int
    scenario_raw: Mapping[str, Any]
    scenario_source: str | None
    parameters: str
    parameter_draw: Mapping[str, Any] | None
    seed: int
    knobs: Mapping[str, Any]
    axis: str

    @property
    def point(self) -> str:
        """The design point without the seed: runs differing only by seed share it."""
        return json.dumps(self.knobs, sort_keys=True)

    def inputs(self) -> dict:
        """The inputs as stored with the run (JSON-ready)."""
        return {
            "scenario": self.scenario_raw,
            "scenario_source": self.scenario_source,
            "parameters": self.parameters,
            "parameter_draw": self.parameter_draw,
            "seed": self.seed,
            "knobs": self.knobs,
            "axis": self.axis,
        }


@dataclass(frozen=True)
class Sweep:
    """A checked sweep file, expanded.

    Attributes:
        name: sweep name.
        source: the sweep file (None when built in code).
        axis: the objective's inner axis.
        knob_names: the varied knobs, in file order (``label`` for cases,
            ``draw`` for parameter draws).
        runs: the runs, in design order.
    """

    name: str
    source: Path | None
    axis: str
    knob_names: tuple[str, ...]
    runs: tuple[RunSpec, ...]


def _canonical(obj: Any) -> str:
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), allow_nan=False)


def _file_digest(path: Path) -> str:
    try:
        return hashlib.sha256(path.read_bytes()).hexdigest()
    except OSError as exc:
        raise ResourceNotFound(f"{path}: cannot read the parameter file ({exc.strerror})") from None


def _nfc_digest(scenario_raw: Mapping[str, Any], source: Path | None) -> str | None:
    """SHA-256 of the NFC's parameter file (None for 'plant', the plant's own set)."""
    from isp_twin.experiments.scenario import resolve_parameters

    value = scenario_raw.get("nfc_parameters", "plant")
    if value == "plant":
        return None
    src = Path(source) if source is not None else None
    return _file_digest(resolve_parameters(value, src, key="nfc_parameters"))


def make_run(
    index: int,
    scenario_raw: Mapping[str, Any],
    scenario_source: Path | None,
    parameters: Path,
    seed: int,
    knobs: Mapping[str, Any],
    axis: str,
    parameter_draw: Mapping[str, Any] | None = None,
    parameters_digest: str | None = None,
) -> RunSpec:
    """One `RunSpec` with its key (the hash of every input that changes its numbers)."""
    digest = parameters_digest or _file_digest(parameters)
    raw = dict(scenario_raw)
    identity = {
        "version": __version__,
        "scenario": raw,
        "parameters_sha256": digest,
        # The NFC's model file changes the numbers as much as the plant's.
        "nfc_parameters_sha256": _nfc_digest(raw, scenario_source),
        "parameter_draw": parameter_draw,
        "seed": int(seed),
        "axis": axis,
    }
    key = hashlib.sha256(_canonical(identity).encode()).hexdigest()
    return RunSpec(
        key=key,
        index=index,
        scenario_raw=raw,
        scenario_source=str(scenario_source) if scenario_source is not None else None,
        parameters=str(parameters),
        parameter_draw=parameter_draw,
        seed=int(seed),
        knobs=dict(knobs),
        axis=axis,
    )


# ---------------------------------------------------------------- checking


def _err(where: str, msg: str) -> ScenarioError:
    return ScenarioError(f"{where}: {msg}")


def _mapping(value: Any, where: str, allowed: tuple[str, ...] | None = None) -> Mapping:
    if not isinstance(value, Mapping):
        raise _err(where, f"expected a mapping of keys, got {value!r}")
    if allowed is not None:
        for key in value:
            if key not in allowed:
                raise _err(
                    f"{where}.{key}" if not where.endswith(":") else f"{where} {key}",
                    f"unknown key{nearest(str(key), allowed)}; allowed: {', '.join(allowed)}",
                )
    return value


def _int(value: Any, where: str, lo: int = 0) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        raise _err(where, f"expected an integer, got {value!r}")
    if value < lo:
        raise _err(where, f"{value} out of range; must be >= {lo}")
    return value


def _number(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise _err(where, f"expected a finite number, got {value!r}")
    return float(value)


def _values(spec: Any, knob: str, where: str) -> list:
    """A grid knob's values: a list, or a range {from, to, num} (num >= 1, evenly spaced)."""
    if isinstance(spec, Mapping):
        _mapping(spec, where, ("from", "to", "num"))
        for k in ("from", "to", "num"):
            if k not in spec:
                raise _err(where, f"a range needs from, to and num (missing '{k}')")
        lo, hi = _number(spec["from"], f"{where}.from"), _number(spec["to"], f"{where}.to")
        num = spec["num"]
        if isinstance(num, bool) or not isinstance(num, int) or num < 1:
            raise _err(f"{where}.num", f"empty range: num must be an integer >= 1, got {num!r}")
        values = [lo] if num == 1 else np.linspace(lo, hi, num).tolist()
        return [check_scenario_value(knob, v, f"{where}[{i}]", where) for i, v in enumerate(values)]
    if isinstance(spec, list):
        if not spec:
            raise _err(where, "empty list of values")
        return [check_scenario_value(knob, v, f"{where}[{i}]", where) for i, v in enumerate(spec)]
    raise _err(where, f"expected a list of values or a range {{from, to, num}}, got {spec!r}")


def _seeds(spec: Any, default: int, where: str) -> list[int]:
    if spec is None:
        return [default]
    if isinstance(spec, list):
        if not spec:
            raise _err(where, "empty list of seeds")
        seeds = [_int(s, f"{where}[{i}]") for i, s in enumerate(spec)]
    else:
        _mapping(spec, where, ("first", "count"))
        first = _int(spec.get("first", default), f"{where}.first")
        count = _int(spec.get("count", 1), f"{where}.count", lo=1)
        seeds = list(range(first, first + count))
    if len(set(seeds)) != len(seeds):
        raise _err(where, "a seed is listed twice")
    return seeds


def _cases(spec: Any, where: str) -> list[dict]:
    if not isinstance(spec, list) or not spec:
        raise _err(where, "expected a non-empty list of settings")
    cases = []
    labels = set()
    for i, case in enumerate(spec):
        w = f"{where}[{i}]"
        _mapping(case, w)
        label = case.get("label", str(i))
        if not isinstance(label, str) or not label:
            raise _err(f"{w}.label", f"expected a non-empty text, got {label!r}")
        if label in labels:
            raise _err(f"{w}.label", f"'{label}' is used twice")
        labels.add(label)
        settings = {
            k: check_scenario_value(str(k), v, f"{w}.{k}") for k, v in case.items() if k != "label"
        }
        cases.append({"label": label, **settings})
    return cases


def _random(spec: Any, where: str) -> tuple[int, int, dict[str, tuple[float, float]]]:
    _mapping(spec, where, ("count", "seed", "knobs"))
    count = _int(spec.get("count", 0), f"{where}.count", lo=1)
    seed = _int(spec.get("seed", 0), f"{where}.seed")
    knobs = _mapping(spec.get("knobs"), f"{where}.knobs")
    if not knobs:
        raise _err(f"{where}.knobs", "no knobs to draw")
    ranges = {}
    for knob, r in knobs.items():
        w = f"{where}.knobs.{knob}"
        _mapping(r, w, ("low", "high"))
        if "low" not in r or "high" not in r:
            raise _err(w, "a random knob needs low and high")
        lo = check_scenario_value(str(knob), r["low"], f"{w}.low", w)
        hi = check_scenario_value(str(knob), r["high"], f"{w}.high", w)
        if isinstance(lo, bool) or not isinstance(lo, (int, float)):
            raise _err(w, "only numeric knobs can be drawn at random")
        if not lo < hi:
            raise _err(w, f"empty range: low {lo!r} must be below high {hi!r}")
        ranges[str(knob)] = (lo, hi)
    return count, seed, ranges


def draw_parameters(params_raw: Mapping, seed: int, draw: int) -> dict:
    """Draw `draw` of a parameter set from its ci95 (see the module doc).

    Args:
        params_raw: the parameter file as parsed YAML.
        seed: the uncertainty seed.
        draw: the draw's index.

    Returns:
        axis -> regime -> field -> drawn value (only parameters with a ci95).
    """
    rng = np.random.default_rng([seed, draw])
    out: dict = {}
    for axis, axis_raw in (params_raw.get("axes") or {}).items():
        for regime in REGIMES:
            entry = (axis_raw or {}).get(regime) or {}
            for f in PAPER_FIELDS:
                value = entry.get(f)
                if not isinstance(value, Mapping) or not value.get("ci95"):
                    continue
                nominal, ci = float(value["value"]), float(value["ci95"])
                x = nominal + rng.standard_normal() * ci / 1.96
                # keep the draw physical: a pole in (0, 1), everything else > 0
                x = min(max(x, 1e-3 * nominal), 1.0 - 1e-9) if f == "a" else max(x, 1e-3 * nominal)
                out.setdefault(axis, {}).setdefault(regime, {})[f] = x
    return out


# ---------------------------------------------------------------- expansion


def _set_key(raw: dict, key_path: str, value: Any) -> None:
    parts = key_path.split(".")
    node = raw
    for part in parts[:-1]:
        node = node.setdefault(part, {})
    if parts[-1] == "rate_amplitude_deg_s":
        node.pop("amplitude_deg", None)  # one amplitude or the other: the knob wins
    if parts[-1] == "amplitude_deg":
        node.pop("rate_amplitude_deg_s", None)
    node[parts[-1]] = value


def parse_sweep(raw: Any, source: str | Path = "<sweep>") -> Sweep:
    """Check a parsed sweep file whole and expand it into runs (nothing runs here).

    Raises:
        ScenarioError: unknown key, empty range, a knob outside its schema
            range, a design point the scenario loader rejects; the message
            names the sweep file and the key path.
        ResourceNotFound: the scenario or parameter file does not exist.
    """
    src = Path(source) if not str(source).startswith("<") else None
    raw = {} if raw is None else raw
    _mapping(raw, f"{source}:", _TOP_KEYS)
    where = f"{source}: "
    name, base = _base_scenario(raw, source, src)
    axis = raw.get("axis", "inner_az")
    if axis not in INNER_AXES:
        raise _err(
            f"{where}axis",
            f"{axis!r} is not allowed{nearest(str(axis), INNER_AXES)}; choose one of "
            f"{', '.join(INNER_AXES)}",
        )
    params_path = _parameters_path(raw, base, src, where)
    design = _Design(
        seeds=_seeds(raw.get("seeds"), base.seed, f"{where}seeds"),
        cases=_cases(raw["cases"], f"{where}cases") if "cases" in raw else [{}],
        grid={
            str(k): _values(v, str(k), f"{where}grid.{k}")
            for k, v in _mapping(raw.get("grid", {}), f"{where}grid").items()
        },
        randoms=_random_draws(raw["random"], f"{where}random") if "random" in raw else [{}],
    )
    if "uncertainty" in raw:
        design = _with_uncertainty(design, raw["uncertainty"], params_path, f"{where}uncertainty")
    _check_design(design, source)
    knob_names = (["label"] if "cases" in raw else []) + list(design.grid)
    knob_names += list(design.randoms[0]) + (["draw"] if design.draws != [None] else [])
    runs = _expand_runs(design, base, params_path, axis, source)
    return Sweep(name=name, source=src, axis=axis, knob_names=tuple(knob_names), runs=tuple(runs))


@dataclass(frozen=True)
class _Design:
    """A sweep's design points before expansion: every run is one of each list's entries."""

    seeds: list[int]
    cases: list[dict]
    grid: dict[str, list]
    randoms: list[dict]
    #: Parameter draws (None: the file's own values), their source and seed.
    draws: list[int | None] = field(default_factory=lambda: [None])
    params_raw: Mapping = field(default_factory=dict)
    uncertainty_seed: int = 0


def _base_scenario(raw: Mapping, source: str | Path, src: Path | None) -> tuple[str, Scenario]:
    """The sweep's name and its base scenario (a closed-loop one, found beside the sweep)."""
    where = f"{source}: "
    if "scenario" not in raw:
        raise _err(f"{source}", "missing key 'scenario' (the base scenario)")
    name = raw.get("name") or (src.stem if src else "sweep")
    if not isinstance(name, str):
        raise _err(f"{where}name", f"expected text, got {name!r}")
    scen_ref = raw["scenario"]
    if not isinstance(scen_ref, str):
        raise _err(f"{where}scenario", f"expected a scenario name or path, got {scen_ref!r}")
    scen_path = Path(scen_ref)
    if src is not None and not scen_path.is_absolute() and (src.parent / scen_path).is_file():
        scen_path = src.parent / scen_path
    try:
        base = load_scenario(scen_path)
    except IspTwinError as exc:
        raise type(exc)(f"{where}scenario: {exc}") from None
    if base.kind != "closed_loop":
        raise _err(
            f"{where}scenario", f"'{scen_ref}' is kind {base.kind}; a sweep runs closed_loop"
        )
    return name, base


def _parameters_path(raw: Mapping, base: Scenario, src: Path | None, where: str) -> Path:
    """The sweep's parameter file (its ``parameters`` key, else the scenario's), absolute."""
    if "parameters" in raw:
        if not isinstance(raw["parameters"], str):
            raise _err(f"{where}parameters", f"expected a file name, got {raw['parameters']!r}")
        try:
            params_path = resolve_parameters(raw["parameters"], src)
        except IspTwinError as exc:
            raise type(exc)(f"{where}parameters: {exc}") from None
    else:
        params_path = base.parameters_path
    return params_path.resolve()


def _random_draws(spec: Any, where: str) -> list[dict]:
    """The ``random`` section's draws: knob -> value, integers for integer ranges."""
    count, rseed, ranges = _random(spec, where)
    rng = np.random.default_rng(rseed)
    randoms = []
    for _ in range(count):
        draw = {}
        for knob, (lo, hi) in ranges.items():
            if isinstance(lo, int) and isinstance(hi, int):
                draw[knob] = int(rng.integers(lo, hi, endpoint=True))
            else:
                draw[knob] = float(rng.uniform(lo, hi))
        randoms.append(draw)
    return randoms


def _with_uncertainty(design: _Design, spec: Any, params_path: Path, where: str) -> _Design:
    """The design with the ``uncertainty`` section's parameter draws (from the file's ci95)."""
    from isp_twin.input_files import load_yaml

    u = _mapping(spec, where, ("draws", "seed"))
    n_draws = _int(u.get("draws", 0), f"{where}.draws", lo=1)
    useed = _int(u.get("seed", 0), f"{where}.seed")
    try:
        params_raw = load_yaml(params_path, "parameter file", ScenarioError)[0] or {}
    except IspTwinError as exc:
        raise type(exc)(f"{where}: {exc}") from None
    if not draw_parameters(params_raw, useed, 0):
        raise _err(where, f"{params_path} gives no ci95 to draw from")
    return dataclasses.replace(
        design, draws=list(range(n_draws)), params_raw=params_raw, uncertainty_seed=useed
    )


def _check_design(design: _Design, source: str | Path) -> None:
    """No knob set by two sections; no more than `MAX_RUNS` runs."""
    case_keys = {k for c in design.cases for k in c if k != "label"}
    random_keys = set(design.randoms[0])
    grid_keys = set(design.grid)
    for a, b, both in (
        (grid_keys, case_keys, "grid and cases"),
        (grid_keys, random_keys, "grid and random"),
        (case_keys, random_keys, "cases and random"),
    ):
        if a & b:
            raise _err(f"{source}", f"'{sorted(a & b)[0]}' is set by both {both}")
    total = len(design.cases) * math.prod(len(v) for v in design.grid.values())
    total *= len(design.randoms) * len(design.draws) * len(design.seeds)
    if total > MAX_RUNS:
        raise _err(f"{source}", f"{total} runs is more than the {MAX_RUNS} a sweep may hold")


def _expand_runs(
    design: _Design, base: Scenario, params_path: Path, axis: str, source: str | Path
) -> list[RunSpec]:
    """Every (case, grid point, random draw, parameter draw, seed), each checked by the
    scenario loader; identical runs kept once."""
    base_raw = scenario_to_raw(base)
    digest = _file_digest(params_path)
    runs: list[RunSpec] = []
    keys: set[str] = set()
    draw_cache: dict[int, dict] = {}
    grid = design.grid
    for case, values, rdraw, d in itertools.product(
        design.cases, itertools.product(*grid.values()), design.randoms, design.draws
    ):
        settings = {k: v for k, v in case.items() if k != "label"}
        settings.update(zip(grid, values))
        settings.update(rdraw)
        scenario_raw = json.loads(json.dumps(base_raw))
        for knob, value in settings.items():
            _set_key(scenario_raw, knob, value)
        label = ", ".join(f"{k}={v}" for k, v in settings.items()) or "the base scenario"
        try:
            scenario = parse_scenario(scenario_raw, base.source or "<scenario>")
        except ScenarioError as exc:
            raise _err(f"{source}", f"the run with {label}: {exc}") from None
        scenario_raw = scenario_to_raw(dataclasses.replace(scenario, name=base.name))
        knobs = {"label": case["label"]} if "label" in case else {}
        knobs.update((k, settings[k]) for k in settings if k not in knobs)
        pdraw = None
        if d is not None:
            knobs["draw"] = d
            pdraw = draw_cache.setdefault(
                d, draw_parameters(design.params_raw, design.uncertainty_seed, d)
            )
        for seed in design.seeds:
            run = make_run(
                len(runs), scenario_raw, base.source, params_path, seed, knobs, axis, pdraw, digest
            )
            # identical inputs (e.g. two random draws of an integer knob) are one run
            if run.key not in keys:
                keys.add(run.key)
                runs.append(run)
    return runs


def load_sweep(path: str | Path) -> Sweep:
    """Load, check and expand a sweep file (see `parse_sweep`); ``1e4`` reads as a number."""
    from isp_twin.input_files import load_yaml

    path = Path(path)
    raw, _ = load_yaml(path, "sweep file", ScenarioError)
    return parse_sweep(raw, path)


def scenario_of(spec: RunSpec) -> Scenario:
    """The run's scenario, rebuilt from its spec."""
    return parse_scenario(spec.scenario_raw, spec.scenario_source or "<scenario>")

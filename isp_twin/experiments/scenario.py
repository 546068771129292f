"""Scenarios: the typed, validated description of one experiment (YAML files).

A scenario file is a tree of mappings; each level is a frozen dataclass below,
each key a field. Keys carry their unit where it is not SI (`freq_hz`,
`duration_s`, `kp_digit_per_count`). The loader rejects unknown keys with the
full key path and the nearest valid key, wrong types, and out-of-range values;
the same field metadata produce the exported JSON Schema
(`scenario_json_schema`, shipped as `scenarios/scenario.schema.json`), so an
editor checks files the way the loader does.

Units at the edge: the paper gives rates in deg/s, angles in deg, the
amplifier command in digits and the gyro in counts; the file keeps those, and
the runner converts them once.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import math
import types
import typing
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

from isp_twin.errors import ResourceNotFound, ScenarioError, nearest
from isp_twin.resources import default_parameters_path, resource_root
from isp_twin.vocabulary import GIMBAL_AXES, INNER_AXES, OUTER_AXES, TABLE_JOINTS

__all__ = [
    "CONTROL_DT",
    "Motion",
    "Turntable",
    "PIGains",
    "Notch",
    "NFC",
    "AxisController",
    "Controller",
    "GyroModel",
    "ResolverModel",
    "Follower",
    "InitialAngles",
    "Metrics",
    "Record",
    "OpenLoopCommand",
    "OpenLoop",
    "Scenario",
    "load_scenario",
    "parse_scenario",
    "scenario_to_raw",
    "check_scenario_value",
    "scenario_json_schema",
    "scenario_json_schema_text",
]

#: The paper's sample period T = 1 ms (Sect. 2.1): controller and twin step.
CONTROL_DT = 1e-3
NYQUIST_HZ = 0.5 / CONTROL_DT


def _f(default: Any, doc: str, **limits: Any) -> Any:
    """A field with a description and limits (min, max, exclusive_min, exclusive_max)."""
    meta = {"doc": doc, **limits}
    if isinstance(default, (dict, list)) or dataclasses.is_dataclass(default):
        return field(default_factory=lambda: default, metadata=meta)
    return field(default=default, metadata=meta)


def _sub(cls: type, doc: str) -> Any:
    return field(default_factory=cls, metadata={"doc": doc})


# ---------------------------------------------------------------- the tree


@dataclass(frozen=True)
class Motion:
    """One turntable axis: a sinusoidal rate, its angle starting at 0.

    ``omega(t) = A*sin(2*pi*f*t + phase)`` (waveform sine) or ``A*cos(...)``
    (waveform cosine), A = `rate_amplitude_deg_s`; the angle is its integral
    from 0, e.g. the paper's isolation input pi*cos(2*pi*t/6) deg/s is the
    angle 3*sin(2*pi*t/6) deg. Give the amplitude either as a rate or as
    `amplitude_deg` (angle amplitude = rate amplitude / (2*pi*f)).
    """

    rate_amplitude_deg_s: float = _f(0.0, "rate amplitude [deg/s]", min=0.0)
    amplitude_deg: float | None = _f(
        None, "angle amplitude [deg], alternative to rate_amplitude_deg_s", min=0.0
    )
    freq_hz: float = _f(0.5, "frequency [Hz]", exclusive_min=0.0, exclusive_max=NYQUIST_HZ)
    phase_deg: float = _f(0.0, "phase of the rate sinusoid [deg]")
    waveform: Literal["sine", "cosine"] = _f("sine", "shape of the rate: sine or cosine")

    @property
    def rate_amplitude(self) -> float:
        """Rate amplitude [rad/s]."""
        if self.amplitude_deg is not None:
            return math.radians(self.amplitude_deg) * 2 * math.pi * self.freq_hz
        return math.radians(self.rate_amplitude_deg_s)


@dataclass(frozen=True)
class Turntable:
    """The flight-simulation turntable (the carrier): one motion per axis (default at rest)."""

    table_yaw: Motion = _sub(Motion, "yaw (outer turntable axis, about the vertical)")
    table_pitch: Motion = _sub(Motion, "pitch")
    table_roll: Motion = _sub(Motion, "roll")

    def motions(self) -> dict[str, Motion]:
        return {a: getattr(self, a) for a in TABLE_JOINTS}


@dataclass(frozen=True)
class PIGains:
    """PI gains in the paper's units: amplifier digits per gyro count (Ki per sample)."""

    kp_digit_per_count: float = _f(3.568, "proportional gain (paper: 3.568)", min=0.0)
    ki_digit_per_count: float = _f(0.0714, "integral gain per sample (paper: 0.0714)", min=0.0)


@dataclass(frozen=True)
class Notch:
    """The rate loop's notch filter (paper: present, parameters not given)."""

    enabled: bool = _f(True, "use the notch")
    freq_hz: float = _f(300.0, "centre frequency [Hz]", exclusive_min=0.0, exclusive_max=NYQUIST_HZ)
    q: float = _f(4.0, "quality factor (centre / -3 dB width)", exclusive_min=0.0)
    depth: float = _f(0.1, "gain at the centre (0: full notch)", min=0.0, max=1.0)


@dataclass(frozen=True)
class NFC:
    """Friction feed-forward, Eq. 11-14."""

    enabled: bool = _f(False, "add the friction feed-forward")
    gamma: float = _f(
        0.95,
        "attenuation factor of Eq. 13 (paper: 0.95, range 0.90-0.98)",
        exclusive_min=0.0,
        max=1.0,
    )
    taps: int = _f(4, "moving-average length of Eq. 12 (paper: 4)", min=1, max=100)
    rest_rate_deg_s: float = _f(
        0.0,
        "|omega_2| at or below which the axis counts as at rest [deg/s] (0: the "
        "resolver did not change over its rate window)",
        min=0.0,
    )


@dataclass(frozen=True)
class AxisController:
    """The inner rate loop of one inner gimbal."""

    pi_form: Literal["series", "parallel"] = _f(
        "series",
        "PI form (paper: not given; rig knob pi_form): series u = kp*(e + ki*sum(e)) or "
        "parallel u = kp*e + ki*sum(e)",
    )
    pi: PIGains = _sub(PIGains, "PI gains used without NFC (paper: Kp 3.568, Ki 0.0714)")
    pi_nfc: PIGains = field(
        default_factory=lambda: PIGains(3.0, 0.15),
        metadata={"doc": "PI gains used with NFC (paper: Kp 3.0, Ki 0.15)"},
    )
    notch: Notch = _sub(Notch, "notch filter")
    bound_digits: float = _f(2000.0, "bound of the control quantity [digits]", exclusive_min=0.0)
    nfc: NFC = _sub(NFC, "friction feed-forward")

    @property
    def gains(self) -> PIGains:
        """The PI gains in force (pi_nfc when NFC is on, as in the paper)."""
        return self.pi_nfc if self.nfc.enabled else self.pi


@dataclass(frozen=True)
class Controller:
    """Both inner rate loops."""

    inner_az: AxisController = _sub(AxisController, "inner azimuth rate loop")
    inner_el: AxisController = _sub(AxisController, "inner elevation rate loop")

    def axis(self, name: str) -> AxisController:
        return getattr(self, name)


@dataclass(frozen=True)
class GyroModel:
    """The inner gimbals' rate gyros (see `isp_twin.control.gyro`)."""

    scale_count_per_deg_s: float = _f(
        70.0,
        "gyro counts per deg/s (rig knob gyro_scale, fitted: docs/calibration.md)",
        exclusive_min=0.0,
    )
    noise_deg_s: float = _f(0.01, "white noise std per sample [deg/s]", min=0.0)
    bandwidth_hz: float = _f(200.0, "first-order bandwidth [Hz]", exclusive_min=0.0)
    sample_every: int = _f(1, "a new reading every this many 1 ms samples", min=1, max=1000)


@dataclass(frozen=True)
class ResolverModel:
    """The gimbals' angle sensors (see `isp_twin.control.resolver`)."""

    resolution_deg: float = _f(
        360.0 / 2**20, "angle quantum [deg] (20-bit converter)", exclusive_min=0.0
    )
    rate_window: int = _f(10, "samples spanned by the rate difference", min=1, max=1000)


@dataclass(frozen=True)
class Follower:
    """Outer gimbals following the inner gimbals' angles (Sect. 4.2)."""

    enabled: bool = _f(True, "outer gimbals follow (off: they are held by their own loop at 0)")
    kp_digit_per_deg: float = _f(2000.0, "proportional gain [digits/deg]", min=0.0)
    ki_digit_per_deg: float = _f(2.0, "integral gain per sample [digits/deg]", min=0.0)
    kd_digit_per_deg_s: float = _f(20.0, "rate damping [digits/(deg/s)]", min=0.0)
    bound_digits: float = _f(2000.0, "command bound [digits]", exclusive_min=0.0)
    inner_az_center_deg: float = _f(
        -1.5,
        "inner_az angle the outer_az follower holds it at [deg] (off 0: see "
        "docs/calibration.md, Table 2's gain jumps at Y = 0)",
        min=-3.0,
        max=3.0,
    )
    inner_el_center_deg: float = _f(
        1.5,
        "inner_el angle the outer_el follower holds it at [deg] (mirrored)",
        min=-3.0,
        max=3.0,
    )


@dataclass(frozen=True)
class InitialAngles:
    """Gimbal angles at t = 0 [deg] (relative, as the resolvers read them)."""

    inner_az: float = _f(0.0, "inner azimuth [deg]", min=-3.5, max=3.5)
    inner_el: float = _f(0.0, "inner elevation [deg]", min=-3.5, max=3.5)
    outer_az: float = _f(0.0, "outer azimuth [deg]", min=-90.0, max=90.0)
    outer_el: float = _f(0.0, "outer elevation [deg]", min=-90.0, max=90.0)

    def as_dict(self) -> dict[str, float]:
        return {a: getattr(self, a) for a in INNER_AXES + OUTER_AXES}


@dataclass(frozen=True)
class Metrics:
    """Which part of the run the metrics use."""

    skip_s: float | None = _f(
        None,
        "discard the first skip_s seconds (default: one period of the slowest "
        "turntable motion, the transient from rest)",
        min=0.0,
    )


@dataclass(frozen=True)
class Record:
    """Recording options."""

    decimation: int = _f(
        1,
        "keep every n-th sample in the run's record (metrics use every sample)",
        min=1,
        max=1000,
    )


@dataclass(frozen=True)
class OpenLoopCommand:
    """``offset + amplitude*cos(2*pi*f*t)`` [digits] (Eq. 4: 950, 0.5 Hz, 0; Eq. 7 offset -200)."""

    amplitude_digits: float = _f(950.0, "amplitude [digits]", min=0.0)
    freq_hz: float = _f(0.5, "frequency [Hz]", exclusive_min=0.0, exclusive_max=NYQUIST_HZ)
    offset_digits: float = _f(0.0, "offset [digits]")


@dataclass(frozen=True)
class OpenLoop:
    """The open-loop experiment (kind: open_loop): one gimbal driven, base at rest."""

    # Literal of a tuple: the choices are the vocabulary's (typing expands it).
    axis: Literal[GIMBAL_AXES] = _f("inner_az", "the driven gimbal")
    command: OpenLoopCommand = _sub(OpenLoopCommand, "the drive signal")
    initial_angle_deg: float = _f(0.0, "gimbal angle at t = 0 [deg]", min=-4.0, max=4.0)


@dataclass(frozen=True)
class Scenario:
    """One experiment.

    Attributes beyond the file's keys: `source` (the file, None when built in
    code), `text` (its text) and `parameters_path` (the parameter file, resolved).
    """

    name: str = _f(
        "",
        "short name, also the default recording's file name: no '/' or '\\' (default: the file's stem)",
    )
    description: str = _f("", "what the scenario reproduces")
    kind: Literal["closed_loop", "open_loop"] = _f("closed_loop", "experiment type")
    # 600 s at 1 kHz is ~130 MB of recorded signals; longer runs are not a use case.
    duration_s: float = _f(10.0, "simulated time [s]", exclusive_min=0.0, max=600.0)
    seed: int = _f(0, "noise seed", min=0)
    parameters: str = _f(
        "paper_table2",
        "parameter file: a path relative to the scenario file, or a shipped name "
        "under models/params (default: the paper's Table 2)",
    )
    rig: str = _f(
        "paper_rig",
        "rig file holding the settings the paper leaves unstated: a path relative to the "
        "scenario file, or a shipped name under models/rigs (default: the paper's rig); "
        "keys the scenario sets itself override the rig's",
    )
    nfc_parameters: str = _f(
        "twin_identified",
        "the model the NFC compensates with (rig knob nfc_model): a parameter file (a path "
        "relative to the scenario file, or a shipped name under models/params; default: the "
        "model identified on the twin's Eq. 7 runs) or 'plant' (the scenario's own parameter "
        "file: an exact model)",
    )
    turntable: Turntable = _sub(Turntable, "carrier motion")
    controller: Controller = _sub(Controller, "inner rate loops")
    gyro: GyroModel = _sub(GyroModel, "gyro model")
    resolver: ResolverModel = _sub(ResolverModel, "resolver model")
    follower: Follower = _sub(Follower, "outer-gimbal followers")
    initial_angles_deg: InitialAngles = _sub(InitialAngles, "gimbal angles at t = 0 [deg]")
    metrics: Metrics = _sub(Metrics, "metrics window")
    record: Record = _sub(Record, "recording options")
    open_loop: OpenLoop = _sub(OpenLoop, "open-loop experiment (kind: open_loop)")
    source: Path | None = field(default=None, compare=False, metadata={"internal": True})
    text: str = field(default="", compare=False, repr=False, metadata={"internal": True})

    @property
    def parameters_path(self) -> Path:
        """The parameter file: relative to the scenario's folder, or a shipped name."""
        return resolve_parameters(self.parameters, self.source)

    @property
    def rig_path(self) -> Path:
        """The rig file: relative to the scenario's folder, or a shipped name."""
        from isp_twin.experiments.rig import resolve_rig

        return resolve_rig(self.rig, self.source)

    @property
    def nfc_parameters_path(self) -> Path | None:
        """The NFC's parameter file, or None when it compensates with the plant's own set."""
        if self.nfc_parameters == "plant":
            return None
        return resolve_parameters(self.nfc_parameters, self.source, key="nfc_parameters")

    @property
    def skip_s(self) -> float:
        """Seconds discarded before the metrics (see `Metrics`)."""
        if self.metrics.skip_s is not None:
            return self.metrics.skip_s
        freqs = [m.freq_hz for m in self.turntable.motions().values() if m.rate_amplitude > 0]
        return 1.0 / min(freqs) if freqs else 0.0

    def with_nfc(self, enabled: bool) -> Scenario:
        """The same scenario with NFC switched on or off on both inner loops."""
        axes = {
            a: dataclasses.replace(
                self.controller.axis(a),
                nfc=dataclasses.replace(self.controller.axis(a).nfc, enabled=enabled),
            )
            for a in INNER_AXES
        }
        return dataclasses.replace(self, controller=Controller(**axes))


def resolve_parameters(value: str, source: Path | None, key: str = "parameters") -> Path:
    """Resolve the `parameters` key (see `Scenario.parameters_path`), or another key naming a parameter file."""
    if value == "paper_table2":
        return default_parameters_path()
    path = Path(value)
    candidates = []
    if source is not None and not path.is_absolute():
        candidates.append(source.parent / path)
    candidates.append(path)
    shipped = resource_root() / "models" / "params"
    candidates += [shipped / path.name, shipped / f"{path.name}.yaml"]
    for c in candidates:
        if c.is_file():
            return c
    available = sorted(p.stem for p in shipped.glob("*.yaml"))
    raise ResourceNotFound(
        f"{source or 'scenario'}: {key}: file '{value}' not found; shipped: {', '.join(available)}"
    )


# ---------------------------------------------------------------- loading


def _fields(cls) -> list[dataclasses.Field]:
    return [f for f in dataclasses.fields(cls) if not f.metadata.get("internal")]


@functools.cache  # resolving the hints is most of a parse; sweeps parse once per run
def _hints(cls) -> dict[str, Any]:
    return typing.get_type_hints(cls)


def _unwrap_optional(tp) -> tuple[Any, bool]:
    if typing.get_origin(tp) in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(tp) if a is not type(None)]
        return args[0], True
    return tp, False


def _check_range(value: float, meta: Mapping, where: str) -> None:
    lo, hi = meta.get("min"), meta.get("max")
    xlo, xhi = meta.get("exclusive_min"), meta.get("exclusive_max")
    bad = (
        (lo is not None and value < lo)
        or (xlo is not None and value <= xlo)
        or (hi is not None and value > hi)
        or (xhi is not None and value >= xhi)
    )
    if bad:
        allowed = []
        for bound, op in (
            ("min", ">="),
            ("exclusive_min", ">"),
            ("max", "<="),
            ("exclusive_max", "<"),
        ):
            if meta.get(bound) is not None:
                allowed.append(f"{op} {meta[bound]:g}")
        note = " (the Nyquist frequency of the 1 kHz loop)" if xhi == NYQUIST_HZ else ""
        raise ScenarioError(
            f"{where}: {value!r} out of range; must be {' and '.join(allowed)}{note}"
        )


def _convert(tp, raw, meta: Mapping, where: str):
    tp, optional = _unwrap_optional(tp)
    if raw is None:
        if optional:
            return None
        raise ScenarioError(f"{where}: a value is required")
    if dataclasses.is_dataclass(tp):
        return _build(tp, raw, where)
    if typing.get_origin(tp) is Literal:
        choices = typing.get_args(tp)
        if raw not in choices:
            raise ScenarioError(
                f"{where}: {raw!r} is not allowed{nearest(str(raw), choices)}; "
                f"choose one of {', '.join(choices)}"
            )
        return raw
    if tp is bool:
        if not isinstance(raw, bool):
            raise ScenarioError(f"{where}: expected true or false, got {raw!r}")
        return raw
    if tp is int:
        # `1e4` (a float to YAML) names an integer too.
        if isinstance(raw, float) and math.isfinite(raw) and raw.is_integer():
            raw = int(raw)
        if isinstance(raw, bool) or not isinstance(raw, int):
            raise ScenarioError(f"{where}: expected an integer, got {raw!r}")
        _check_range(raw, meta, where)
        return raw
    if tp is float:
        if isinstance(raw, bool) or not isinstance(raw, (int, float)):
            raise ScenarioError(f"{where}: expected a number, got {raw!r}")
        if not math.isfinite(raw):
            raise ScenarioError(f"{where}: must be finite, got {raw!r}")
        _check_range(float(raw), meta, where)
        return float(raw)
    if tp is str:
        if not isinstance(raw, str):
            raise ScenarioError(f"{where}: expected text, got {raw!r}")
        return raw
    raise TypeError(f"unsupported scenario field type {tp}")  # a bug in this module


def _nearest_key(key: str, keys) -> str:
    """Did-you-mean hint, also matching a key's stem before its unit (kpp -> kp_...)."""
    hint = nearest(key, keys)
    if hint:
        return hint
    stems = {k.split("_")[0]: k for k in keys}
    match = nearest(key.split("_")[0], stems)
    if match:
        return f" (did you mean '{stems[match.split(chr(39))[1]]}'?)"
    return ""


def _build(cls, raw, where: str):
    prefix = f"{where}." if not where.endswith(": ") else where
    if not isinstance(raw, Mapping):
        raise ScenarioError(f"{where.rstrip(': ')}: expected a mapping of keys, got {raw!r}")
    fields = {f.name: f for f in _fields(cls)}
    for key in raw:
        if key not in fields:
            raise ScenarioError(
                f"{prefix}{key}: unknown key{_nearest_key(str(key), fields)}; "
                f"allowed: {', '.join(fields)}"
            )
    hints = _hints(cls)
    values = {
        name: _convert(hints[name], raw[name], fields[name].metadata, f"{prefix}{name}")
        for name in raw
    }
    obj = cls(**values)
    _check_object(obj, raw, where)
    return obj


def _check_object(obj, raw, where: str) -> None:
    prefix = f"{where}." if not where.endswith(": ") else where
    if isinstance(obj, Motion) and "amplitude_deg" in raw and "rate_amplitude_deg_s" in raw:
        raise ScenarioError(
            f"{prefix}amplitude_deg: give either amplitude_deg or rate_amplitude_deg_s, not both"
        )


def parse_scenario(raw: Any, source: str | Path = "<scenario>", text: str = "") -> Scenario:
    """Build a `Scenario` from parsed YAML; errors name `source` and the key path."""
    from isp_twin.experiments.rig import load_rig, resolve_rig

    source_path = Path(source) if not str(source).startswith("<") else None
    raw = raw if raw is not None else {}
    scenario = _build(Scenario, raw, f"{source}: ")
    # The rig's settings fill the keys the file leaves unset (the file's own keys win).
    rig = load_rig(resolve_rig(scenario.rig, source_path))
    scenario = _build(Scenario, rig.fill(raw, scenario), f"{source}: ")
    if scenario.name and (set(scenario.name) & {"/", "\\", "\0"} or scenario.name in (".", "..")):
        # The name becomes the file name of the default recording.
        raise ScenarioError(
            f"{source}: name: {scenario.name!r} is not a name (no '/', '\\', '.' or '..'); "
            "use --recording PATH to write elsewhere"
        )
    name = scenario.name or (source_path.stem if source_path else "scenario")
    scenario = dataclasses.replace(scenario, name=name, source=source_path, text=text)
    if scenario.kind == "closed_loop":
        if not any(m.rate_amplitude > 0 for m in scenario.turntable.motions().values()):
            raise ScenarioError(
                f"{source}: turntable: a closed-loop scenario needs at least one moving "
                "turntable axis (the carrier turbulence that J is measured against)"
            )
        if scenario.skip_s >= scenario.duration_s:
            raise ScenarioError(
                f"{source}: duration_s: {scenario.duration_s:g} s leaves nothing after the "
                f"{scenario.skip_s:g} s discarded before the metrics (metrics.skip_s)"
            )
    return scenario


def load_scenario(path: str | Path, overrides: Mapping[str, Any] | None = None) -> Scenario:
    """Load and validate a scenario file (a path, or a bare shipped name).

    Args:
        path: the file, or a shipped scenario's name.
        overrides: top-level keys that replace the file's (e.g. ``rig``).

    Raises:
        ResourceNotFound: no such file.
        ScenarioError: invalid YAML, unknown key, wrong type or out-of-range
            value; the message names the file and the key path.
    """
    from isp_twin.input_files import load_yaml
    from isp_twin.resources import find_scenario

    path = find_scenario(path)
    raw, text = load_yaml(path, "scenario file", ScenarioError)
    if overrides:
        raw = {**raw, **overrides}
    return parse_scenario(raw, path, text)


def scenario_to_raw(scenario: Scenario) -> dict:
    """The scenario as a plain mapping of every key (defaults included), as a file gives it.

    ``parse_scenario(scenario_to_raw(s), s.source)`` builds an equal scenario.
    Unset optional keys (None) are left out, and so is a motion's
    `rate_amplitude_deg_s` when its `amplitude_deg` is given (one or the other).
    """

    def raw(obj):
        out = {}
        for f in _fields(type(obj)):
            value = getattr(obj, f.name)
            if value is None:
                continue
            out[f.name] = raw(value) if dataclasses.is_dataclass(value) else value
        if isinstance(obj, Motion) and obj.amplitude_deg is not None:
            del out["rate_amplitude_deg_s"]
        return out

    return raw(scenario)


def check_scenario_value(
    key_path: str, value: Any, where: str, key_where: str | None = None
) -> Any:
    """Check one value against the scenario schema at a dotted key path.

    Args:
        key_path: e.g. ``controller.inner_az.nfc.gamma``.
        value: the value to check (as a YAML file would give it).
        where: how the error names the place (e.g. ``sweep.yaml: grid.<key>[2]``).
        key_where: how an error in the key path itself names the place
            (default: `where`).

    Returns:
        The value converted as the loader would.

    Raises:
        ScenarioError: unknown key (with the nearest valid key), a key that
            holds a section rather than a value, wrong type, out of range.
    """
    kw = key_where or where
    cls = Scenario
    parts = key_path.split(".")
    for i, part in enumerate(parts):
        fields = {f.name: f for f in _fields(cls)}
        if part not in fields:
            done = ".".join(parts[:i])
            section = f" in '{done}'" if done else ""
            raise ScenarioError(
                f"{kw}: unknown scenario key '{part}'{section}{_nearest_key(part, fields)}; "
                f"allowed: {', '.join(fields)}"
            )
        tp, _ = _unwrap_optional(_hints(cls)[part])
        if i < len(parts) - 1:
            if not dataclasses.is_dataclass(tp):
                raise ScenarioError(f"{kw}: '{'.'.join(parts[: i + 1])}' holds no keys")
            cls = tp
        elif dataclasses.is_dataclass(tp):
            raise ScenarioError(
                f"{kw}: '{key_path}' is a section; sweep one of its keys: "
                f"{', '.join(f.name for f in _fields(tp))}"
            )
    return _convert(_hints(cls)[parts[-1]], value, fields[parts[-1]].metadata, where)


# ---------------------------------------------------------------- JSON Schema


def _schema_of(tp, meta: Mapping) -> dict:
    tp, optional = _unwrap_optional(tp)
    if dataclasses.is_dataclass(tp):
        out = _object_schema(tp)
    elif typing.get_origin(tp) is Literal:
        out = {"enum": list(typing.get_args(tp))}
    else:
        out = {
            bool: {"type": "boolean"},
            int: {"type": "integer"},
            float: {"type": "number"},
            str: {"type": "string"},
        }[tp]
        out = dict(out)
        for key, js in (
            ("min", "minimum"),
            ("max", "maximum"),
            ("exclusive_min", "exclusiveMinimum"),
            ("exclusive_max", "exclusiveMaximum"),
        ):
            if meta.get(key) is not None:
                out[js] = meta[key]
    if optional:
        out = {"anyOf": [out, {"type": "null"}]}
    if meta.get("doc"):
        out["description"] = meta["doc"]
    return out


def _object_schema(cls) -> dict:
    hints = _hints(cls)
    props = {}
    for f in _fields(cls):
        props[f.name] = _schema_of(hints[f.name], f.metadata)
        if f.default is not dataclasses.MISSING and not dataclasses.is_dataclass(f.default):
            props[f.name]["default"] = f.default
    return {
        "type": "object",
        "description": (cls.__doc__ or "").strip().splitlines()[0],
        "properties": props,
        "additionalProperties": False,
    }


def scenario_json_schema() -> dict:
    """The JSON Schema (draft 2020-12) of a scenario file."""
    schema = _object_schema(Scenario)
    return {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "$id": "https://isp-twin/scenario.schema.json",
        "title": "isp-twin scenario",
        **schema,
    }


def scenario_json_schema_text() -> str:
    """The schema as the text of `scenarios/scenario.schema.json`."""
    return json.dumps(scenario_json_schema(), indent=2) + "\n"

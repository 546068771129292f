"""Parameter sets: the per-regime axis parameters of Eq. 6, loaded from YAML.

A parameter file holds, for each gimbal axis, the paper's six parameters in
each of the four friction regimes (Table 2 form), with optional 95 %
confidence half-widths and optional extra effects found by `diagnose`.

Units of the paper form (the file's units; the paper leaves the torque unit
implicit, so it is a free "torque unit", tu):

=====  ====================================  =========================
name   meaning                               unit
=====  ====================================  =========================
a      pole of the rate response per sample  1 (0 < a < 1)
b      inverse inertia per sample            (deg/s) / tu per sample
Ke     amplifier/motor gain                  tu / digit
Ts     static (breakaway) friction torque    tu (magnitude, > 0)
Tc     Coulomb friction torque               tu (magnitude, > 0)
alpha  Stribeck curve factor                 1 / (deg/s)
=====  ====================================  =========================

Only the products b·Ke, b·Ts, b·Tc are determined by rate data (the paper's
"multi-value problem"); `RateParams` holds exactly those, converted once to SI.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any

import numpy as np

from isp_twin.errors import ParameterError, nearest
from isp_twin.model.rate_layout import RateLayout
from isp_twin.output.files import write_text_atomic
from isp_twin.units import DEG
from isp_twin.vocabulary import GIMBAL_AXES, REGIMES, SIDE_SOURCES

__all__ = [
    "REGIMES",
    "PAPER_FIELDS",
    "RegimeParams",
    "EffectSpec",
    "FittedWith",
    "AxisParams",
    "ParameterSet",
    "RateParams",
    "RATE_LAYOUT",
    "sample_hold_factor",
    "load_parameters",
    "save_parameters",
]

#: The six per-regime parameters, in Eq. 8 order.
PAPER_FIELDS: tuple[str, ...] = ("a", "b", "Ke", "Ts", "Tc", "alpha")

UNITS: dict[str, str] = {
    "a": "1 (pole per sample)",
    "b": "(deg/s)/tu per sample",
    "Ke": "tu/digit",
    "Ts": "tu",
    "Tc": "tu",
    "alpha": "1/(deg/s)",
}


@dataclass(frozen=True)
class RegimeParams:
    """The six Eq. 6 parameters of one regime, in the paper's units (see module doc)."""

    a: float
    b: float
    Ke: float
    Ts: float
    Tc: float
    alpha: float

    def as_tuple(self) -> tuple[float, ...]:
        return tuple(getattr(self, f) for f in PAPER_FIELDS)


@dataclass(frozen=True)
class EffectSpec:
    """An extra physical effect on an axis (added by `diagnose`).

    Attributes:
        name: effect type, e.g. ``cogging`` (see `isp_twin.diagnosis.effects`).
        params: its parameters, SI units, names carry the unit where not SI.
    """

    name: str
    params: Mapping[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class FittedWith:
    """How an axis' rate parameters were fitted: the model they belong to.

    Written by `identify` and `diagnose` as the axis' ``fitted_with:`` block;
    `diagnose` simulates with it (docs/identification.md). A file without the
    block means the defaults of `isp_twin.model.substep_model.DEFAULT_INTEGRATION`
    and a read-out timing chosen from the data.

    Attributes:
        substeps: integration steps per sample m [1] (1..100; 1 with all
            three options off is the paper's Eq. 6).
        midpoint_friction: sliding friction at each sub-step's mean rate.
        split_reversals: a sub-step that reaches rate 0 decides stick or
            breakaway for its remaining part.
        exact_effect_hold: effects' accelerations held by their exact
            zero-order hold over the sample.
        midstep_angle: torques of the measured angle taken at the step's
            mean angle (optional in a file: absent means false, the model
            files written before it was fitted with).
        rest_drive_gain: at rest the motor gain of the regime the total
            drive breaks towards, not of the command's sign (optional as
            ``midstep_angle``: absent means false).
        split_sides: a sub-step whose angle crosses 0 takes each side's
            regime for its part of it (optional as ``midstep_angle``).
        gyro_average: the gyro reads the rate averaged over the sample (else
            the rate at the sample instant).
        side_shift_steps: the half-plane is read from the angle at step start
            + this fraction of a step (a sub-step) [steps], 0 <= x < 1.
        side_source: the angle the half-plane was read from, one of
            `SIDE_SOURCES` (``measured``: the angle fused with the integrated
            rate; ``raw``: the angle as measured; optional: absent means
            ``measured``, the default of both commands before it was kept).
    """

    substeps: int
    midpoint_friction: bool
    split_reversals: bool
    exact_effect_hold: bool
    gyro_average: bool
    side_shift_steps: float
    midstep_angle: bool = False
    rest_drive_gain: bool = False
    split_sides: bool = False
    side_source: str = "measured"


#: Keys of a ``fitted_with:`` block, in `FittedWith` order.
FITTED_WITH_KEYS: tuple[str, ...] = (
    "substeps",
    "midpoint_friction",
    "split_reversals",
    "exact_effect_hold",
    "gyro_average",
    "side_shift_steps",
    "midstep_angle",
    "rest_drive_gain",
    "split_sides",
    "side_source",
)
#: Keys a ``fitted_with:`` block may leave out: options added after files
#: were written without them; absent means false, the rule those files were
#: fitted with (``side_source``, also optional, is a name: absent means
#: ``measured``).
FITTED_WITH_OPTIONAL: tuple[str, ...] = ("midstep_angle", "rest_drive_gain", "split_sides")
#: Largest sub-step count a file or ``--substeps`` may ask for.
MAX_SUBSTEPS = 100


@dataclass(frozen=True)
class AxisParams:
    """One axis: four regimes in `REGIMES` order, optional CI and effects.

    Attributes:
        regimes: the four `RegimeParams`, order R+, R-, L+, L-.
        ci95: 95 % confidence half-widths per regime (None where not known).
        identified: per regime, False where the regime kept its prior value.
        effects: extra effects, applied by the axis model and the twin.
        note: free text (source of the numbers).
        fitted_with: the model the rate parameters were fitted with (None:
            not recorded, the defaults; `FittedWith`).
    """

    regimes: tuple[RegimeParams, ...]
    ci95: tuple[RegimeParams | None, ...] = (None, None, None, None)
    identified: tuple[bool, ...] = (True, True, True, True)
    effects: tuple[EffectSpec, ...] = ()
    note: str = ""
    fitted_with: FittedWith | None = None

    def regime(self, name: str) -> RegimeParams:
        return self.regimes[REGIMES.index(name)]

    def rate_params(self) -> RateParams:
        return RateParams.from_regimes(self.regimes)


@dataclass(frozen=True)
class ParameterSet:
    """A whole parameter file.

    Attributes:
        name: short name of the set.
        axes: axis name -> `AxisParams` (the keys are a subset of `GIMBAL_AXES`).
        sample_time_s: the sample period T the per-sample parameters refer to [s].
        path: the file it came from (None when built in code).
        description: free text.
    """

    name: str
    axes: Mapping[str, AxisParams]
    sample_time_s: float = 1e-3
    path: Path | None = None
    description: str = ""

    def axis(self, name: str) -> AxisParams:
        try:
            return self.axes[name]
        except KeyError:
            raise ParameterError(
                f"{self.path or self.name}: no axis '{name}'{nearest(name, self.axes)}; "
                f"has {', '.join(self.axes)}"
            ) from None

    def with_axis(self, name: str, axis: AxisParams) -> ParameterSet:
        axes = dict(self.axes)
        axes[name] = axis
        return replace(self, axes=axes)


@dataclass(frozen=True)
class RateParams:
    """The identifiable, rate-form parameters of Eq. 6 in SI units.

    Eq. 6 reads, per regime r and per sample,
    ``omega[k] = pole*omega[k-1] + gain*u[k-1] - friction(omega[k-1])`` with
    friction magnitude ``coulomb + (static - coulomb)*exp(-alpha*|omega|)``.
    Every array has shape ``(..., 4)``: an optional batch of parameter sets,
    then the four regimes in `REGIMES` order.

    Attributes:
        pole: a [1].
        gain: b·Ke [rad/s per digit, per sample].
        static: b·Ts [rad/s per sample].
        coulomb: b·Tc [rad/s per sample].
        alpha: curve factor [s/rad].
    """

    pole: np.ndarray
    gain: np.ndarray
    static: np.ndarray
    coulomb: np.ndarray
    alpha: np.ndarray

    @classmethod
    def from_regimes(cls, regimes: tuple[RegimeParams, ...]) -> RateParams:
        p = np.array([r.as_tuple() for r in regimes], dtype=float)  # (4, 6)
        a, b, ke, ts, tc, alpha = p.T
        return cls(
            pole=a,
            gain=b * ke * DEG,
            static=b * ts * DEG,
            coulomb=b * tc * DEG,
            alpha=alpha / DEG,
        )

    @classmethod
    def from_vector(cls, x: np.ndarray) -> RateParams:
        """From ``x`` of shape (..., `RATE_LAYOUT.size`): per regime (pole, gain, static, coulomb, alpha)."""
        table = RATE_LAYOUT.as_table(np.asarray(x, dtype=float))
        return cls(**{f: table[..., i] for i, f in enumerate(RATE_LAYOUT.fields)})

    def to_vector(self) -> np.ndarray:
        """Inverse of `from_vector`: shape (..., `RATE_LAYOUT.size`)."""
        return RATE_LAYOUT.from_table(
            np.stack([getattr(self, f) for f in RATE_LAYOUT.fields], axis=-1)
        )

    def to_regimes(self, b: tuple[float, ...]) -> tuple[RegimeParams, ...]:
        """Back to the paper form, given the (unidentifiable) b of each regime."""
        out = []
        for r in range(len(REGIMES)):
            br = b[r]
            out.append(
                RegimeParams(
                    a=float(self.pole[r]),
                    b=float(br),
                    Ke=float(self.gain[r] / DEG / br),
                    Ts=float(self.static[r] / DEG / br),
                    Tc=float(self.coulomb[r] / DEG / br),
                    alpha=float(self.alpha[r] * DEG),
                )
            )
        return tuple(out)


#: The flat rate vector of `RateParams.to_vector`: per regime in Eq. 8 order
#: (`REGIMES`), RateParams' fields in their declared order.
RATE_LAYOUT = RateLayout(REGIMES, tuple(f.name for f in fields(RateParams)))


def sample_hold_factor(pole) -> np.ndarray:
    """What a constant acceleration held over one sample moves the rate by, over
    ``accel*T``: ``(1 - a)/(-ln a)`` at the pole a = exp(-T/tau) (the zero-order
    hold of a first-order axis; 1 as a -> 1, Eq. 6's ``accel*T``), same shape as `pole`."""
    a = np.clip(np.asarray(pole, dtype=float), 1e-12, 1.0 - 1e-12)
    return (1.0 - a) / -np.log(a)


# ---------------------------------------------------------------- YAML I/O


def _where(path: Path | str, keys: list[str]) -> str:
    return f"{path}: {'.'.join(keys)}"


def _number(value: Any, path, keys) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ParameterError(f"{_where(path, keys)}: expected a number, got {value!r}")
    x = float(value)
    if not math.isfinite(x):
        raise ParameterError(f"{_where(path, keys)}: must be finite, got {value!r}")
    return x


def _check_keys(mapping: Any, allowed, path, keys, required=()) -> None:
    if not isinstance(mapping, Mapping):
        raise ParameterError(f"{_where(path, keys)}: expected a mapping, got {mapping!r}")
    for k in mapping:
        if k not in allowed:
            raise ParameterError(
                f"{_where(path, keys + [str(k)])}: unknown key{nearest(str(k), allowed)}; "
                f"allowed: {', '.join(allowed)}"
            )
    for k in required:
        if k not in mapping:
            raise ParameterError(f"{_where(path, keys + [k])}: missing")


def _parse_regime(raw, path, keys) -> tuple[RegimeParams, RegimeParams | None]:
    _check_keys(raw, PAPER_FIELDS, path, keys, required=PAPER_FIELDS)
    values, cis = {}, {}
    for f in PAPER_FIELDS:
        entry = raw[f]
        k = keys + [f]
        if isinstance(entry, Mapping):
            _check_keys(entry, ("value", "ci95"), path, k, required=("value",))
            values[f] = _number(entry["value"], path, k + ["value"])
            if "ci95" in entry:
                cis[f] = _number(entry["ci95"], path, k + ["ci95"])
                if cis[f] < 0:
                    raise ParameterError(f"{_where(path, k + ['ci95'])}: must be >= 0")
        else:
            values[f] = _number(entry, path, k)
        v = values[f]
        if f == "a" and not 0.0 < v < 1.0:
            raise ParameterError(f"{_where(path, k)}: pole a must lie in (0, 1), got {v}")
        if f != "a" and v <= 0.0:
            raise ParameterError(f"{_where(path, k)}: must be positive, got {v}")
    ci = RegimeParams(**{f: cis.get(f, math.nan) for f in PAPER_FIELDS}) if cis else None
    return RegimeParams(**values), ci


def _parse_effects(raw, path, keys) -> tuple[EffectSpec, ...]:
    if not isinstance(raw, list):
        raise ParameterError(f"{_where(path, keys)}: expected a list of effects")
    out = []
    for i, item in enumerate(raw):
        k = keys + [f"[{i}]"]
        if not isinstance(item, Mapping) or "name" not in item:
            raise ParameterError(f"{_where(path, k)}: an effect needs a 'name'")
        params = item.get("params", {})
        if not isinstance(params, Mapping):
            raise ParameterError(f"{_where(path, k + ['params'])}: expected a mapping")
        out.append(
            EffectSpec(
                name=str(item["name"]),
                params={
                    str(n): _number(v, path, k + ["params", str(n)]) for n, v in params.items()
                },
            )
        )
    return tuple(out)


def _parse_fitted_with(raw, path, keys) -> FittedWith:
    required = tuple(k for k in FITTED_WITH_KEYS if k not in (*FITTED_WITH_OPTIONAL, "side_source"))
    _check_keys(raw, FITTED_WITH_KEYS, path, keys, required=required)
    m = raw["substeps"]
    if isinstance(m, bool) or not isinstance(m, int) or not 1 <= m <= MAX_SUBSTEPS:
        raise ParameterError(
            f"{_where(path, keys + ['substeps'])}: expected an integer from 1 to "
            f"{MAX_SUBSTEPS}, got {m!r}"
        )
    flags = {}
    for k in FITTED_WITH_KEYS[1:5]:
        if not isinstance(raw[k], bool):
            raise ParameterError(
                f"{_where(path, keys + [k])}: expected true or false, got {raw[k]!r}"
            )
        flags[k] = raw[k]
    for k in FITTED_WITH_OPTIONAL:
        flags[k] = raw.get(k, False)
        if not isinstance(flags[k], bool):
            raise ParameterError(
                f"{_where(path, keys + [k])}: expected true or false, got {flags[k]!r}"
            )
    shift = _number(raw["side_shift_steps"], path, keys + ["side_shift_steps"])
    if not 0.0 <= shift < 1.0:
        raise ParameterError(
            f"{_where(path, keys + ['side_shift_steps'])}: must lie in [0, 1) (a fraction of a "
            f"step), got {shift}"
        )
    side = raw.get("side_source", "measured")
    if side not in SIDE_SOURCES:
        raise ParameterError(
            f"{_where(path, keys + ['side_source'])}: expected one of "
            f"{', '.join(SIDE_SOURCES)}, got {side!r}"
        )
    return FittedWith(substeps=m, side_shift_steps=shift, side_source=side, **flags)


def _parse_axis(raw, path, keys) -> AxisParams:
    allowed = REGIMES + ("note", "identified", "effects", "fitted_with")
    _check_keys(raw, allowed, path, keys, required=REGIMES)
    regimes, cis = [], []
    for name in REGIMES:
        r, ci = _parse_regime(raw[name], path, keys + [name])
        regimes.append(r)
        cis.append(ci)
    identified = (True,) * 4
    if "identified" in raw:
        ident = raw["identified"]
        _check_keys(ident, REGIMES, path, keys + ["identified"])
        identified = tuple(bool(ident.get(n, True)) for n in REGIMES)
    effects = _parse_effects(raw.get("effects", []), path, keys + ["effects"])
    fitted_with = None
    if "fitted_with" in raw:
        fitted_with = _parse_fitted_with(raw["fitted_with"], path, keys + ["fitted_with"])
    return AxisParams(
        regimes=tuple(regimes),
        ci95=tuple(cis),
        identified=identified,
        effects=effects,
        note=str(raw.get("note", "")),
        fitted_with=fitted_with,
    )


def load_parameters(path: str | Path) -> ParameterSet:
    """Load and validate a parameter file.

    Raises:
        ResourceNotFound: the file does not exist.
        ParameterError: a key is missing, unknown, or a value is out of range;
            the message names the file and the key path.
    """
    from isp_twin.input_files import load_yaml

    path = Path(path)
    raw, _ = load_yaml(path, "parameter file", ParameterError)
    top = ("name", "description", "sample_time_s", "units", "axes")
    _check_keys(raw, top, path, [], required=("name", "sample_time_s", "units", "axes"))
    if raw["units"] != UNITS:
        raise ParameterError(
            f"{path}: units: must be exactly {UNITS} (the paper form); got {raw['units']}"
        )
    dt = _number(raw["sample_time_s"], path, ["sample_time_s"])
    if dt <= 0:
        raise ParameterError(f"{path}: sample_time_s: must be positive, got {dt}")
    axes_raw = raw["axes"]
    _check_keys(axes_raw, GIMBAL_AXES, path, ["axes"])
    if not axes_raw:
        raise ParameterError(f"{path}: axes: at least one axis is needed")
    axes = {name: _parse_axis(axes_raw[name], path, ["axes", name]) for name in axes_raw}
    return ParameterSet(
        name=str(raw["name"]),
        axes=axes,
        sample_time_s=dt,
        path=path,
        description=str(raw.get("description", "")),
    )


def _round(x: float) -> float:
    return float(f"{x:.6g}")


def parameters_to_dict(params: ParameterSet) -> dict:
    """The YAML structure of a parameter set (inverse of `load_parameters`)."""
    axes = {}
    for name, axis in params.axes.items():
        out: dict[str, Any] = {}
        if axis.note:
            out["note"] = axis.note
        for r, reg, ci in zip(REGIMES, axis.regimes, axis.ci95):
            entry = {}
            for f in PAPER_FIELDS:
                v = _round(getattr(reg, f))
                c = getattr(ci, f) if ci is not None else math.nan
                entry[f] = {"value": v, "ci95": _round(c)} if math.isfinite(c) else v
            out[r] = entry
        if not all(axis.identified):
            out["identified"] = dict(zip(REGIMES, axis.identified))
        if axis.effects:
            out["effects"] = [
                {"name": e.name, "params": {k: _round(v) for k, v in e.params.items()}}
                for e in axis.effects
            ]
        if axis.fitted_with is not None:
            f = axis.fitted_with
            out["fitted_with"] = {
                "substeps": int(f.substeps),
                **{k: bool(getattr(f, k)) for k in FITTED_WITH_KEYS[1:5]},
                "side_shift_steps": float(f.side_shift_steps),
                **{k: bool(getattr(f, k)) for k in FITTED_WITH_OPTIONAL},
                "side_source": str(f.side_source),
            }
        axes[name] = out
    return {
        "name": params.name,
        "description": params.description,
        "sample_time_s": params.sample_time_s,
        "units": dict(UNITS),
        "axes": axes,
    }


def save_parameters(params: ParameterSet, path: str | Path) -> Path:
    """Write a parameter file atomically (never a half-written file)."""
    import yaml

    text = yaml.safe_dump(parameters_to_dict(params), sort_keys=False, width=100)
    return write_text_atomic(path, text)

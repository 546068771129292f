"""Measured open-loop data: loading, checking, deriving the missing signal.

A run is a command ``u`` in and a rate ``omega`` and/or an angle ``theta`` out,
sampled uniformly. The canonical file is a CSV with a header row and the
columns

=======  ====================================================  =======
column   meaning                                               unit
=======  ====================================================  =======
t        time                                                  s
u        motor command (amplifier digits for the paper's ISP,  as given
         N·m for a torque-driven bench: kept as is)
omega    relative rate (rate gyro)                             deg/s
theta    relative angle (resolver / encoder)                   deg
=======  ====================================================  =======

One of ``omega`` and ``theta`` may be missing:

* angle only: the rate is the derivative of a Savitzky-Golay fit (quadratic,
  `DERIVATIVE_WINDOW` samples, centred): zero phase lag (the fit is symmetric,
  offline), and it averages resolver quantization: for white angle noise of
  standard deviation s the rate noise is ``s/dt * sqrt(12/(w(w^2-1)))``
  (w = window), i.e. 0.034*s/dt for w = 11 instead of 0.71*s/dt for a plain
  central difference. A ramp or quadratic is differentiated exactly.
* rate only: the angle is integrated with the rule of the axis model,
  ``theta[k] = theta[k-1] + dt*omega[k]``, from ``theta[0] = initial_angle``
  (0 unless the data description gives one): a rate-gyro-only test does not
  know its absolute angle, and the half-plane split depends on it.

Other layouts (MATLAB ``.mat`` files, CSV with other names or units) are read
through a `DataMapping`: for each canonical signal its source (a CSV column
name, a ``.mat`` variable, or a column index of a ``.mat`` matrix) and a scale
factor or unit to the canonical unit. On the command line it is written
``--map KEY=SOURCE[*SCALE]`` (`parse_map_option`), in a YAML data description
(`load_data_description`) as::

    variable: data            # .mat matrix the column indices refer to
    columns:
      t: 0
      u: 4
      omega: {column: 3, unit: rad/s}
      theta: {column: 2, unit: rad}
    initial_angle_deg: 0.0    # only used when theta is derived

Inside the returned `MeasuredData` everything is SI (rad, rad/s, s); the
command keeps its own unit.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from isp_twin.errors import DataError, ResourceNotFound, nearest
from isp_twin.estimation.simulation_error import SAMPLE_PERIOD_TOLERANCE
from isp_twin.input_files import load_yaml, read_text
from isp_twin.output.files import staged_path
from isp_twin.units import DEG

__all__ = [
    "SIGNALS",
    "MIN_SAMPLES",
    "UNIFORM_TOLERANCE",
    "SAMPLE_PERIOD_TOLERANCE",
    "check_sample_period",
    "unique_names",
    "DERIVATIVE_WINDOW",
    "ColumnSpec",
    "DataMapping",
    "MeasuredData",
    "load_measured",
    "save_measured",
    "parse_map_option",
    "mapping_from_options",
    "load_data_description",
    "differentiate_angle",
    "integrate_rate",
]

#: Canonical signals, in file order.
SIGNALS: tuple[str, ...] = ("t", "u", "omega", "theta")
#: Fewer samples than this cannot be identified from (and are an error).
MIN_SAMPLES = 20
#: Largest allowed deviation of a sample period from the median, relative.
UNIFORM_TOLERANCE = 0.01
#: Savitzky-Golay window [samples] for the rate of angle-only data (odd).
DERIVATIVE_WINDOW = 11

#: Named units a mapping may give, as the factor to the canonical unit
#: (t: s, omega: deg/s, theta: deg; u is never converted).
UNIT_FACTORS: dict[str, dict[str, float]] = {
    "t": {"s": 1.0, "ms": 1e-3},
    "omega": {"deg/s": 1.0, "rad/s": 1.0 / DEG, "rpm": 6.0},
    "theta": {"deg": 1.0, "rad": 1.0 / DEG},
    "u": {},
}


@dataclass(frozen=True)
class ColumnSpec:
    """Where one canonical signal comes from.

    Attributes:
        source: a CSV column name, a ``.mat`` variable name, or a column index
            (int) into the mapping's ``.mat`` matrix variable (or a CSV
            column index).
        scale: factor from the file's values to the canonical unit
            (t s, u unchanged unit, omega deg/s, theta deg).
    """

    source: str | int
    scale: float = 1.0


@dataclass(frozen=True)
class DataMapping:
    """How a file's own columns map to the canonical signals.

    Attributes:
        columns: canonical name (`SIGNALS`) -> `ColumnSpec`; ``t`` and ``u``
            are required, at least one of ``omega`` and ``theta``. Empty:
            the canonical CSV columns (only `initial_angle_deg` is used).
        variable: for ``.mat`` files, the matrix variable that integer column
            indices refer to.
        initial_angle_deg: angle at the first sample [deg] when theta is derived.
        origin: where the mapping came from (for error messages).
    """

    columns: Mapping[str, ColumnSpec] = field(default_factory=dict)
    variable: str | None = None
    initial_angle_deg: float = 0.0
    origin: str = "--map"


@dataclass(frozen=True)
class MeasuredData:
    """One open-loop run. Arrays shape (N,), SI.

    Attributes:
        name: file stem.
        t: time [s], uniform.
        u: command [digits or N·m: the file's command unit].
        omega: relative rate [rad/s].
        angle: angle [rad].
        source: the file it came from (None when made in code).
        dt: sample period [s].
        resolver: the angle as measured [rad] where `angle` is the fused
            one (`isp_twin.identification.side_angle.with_side_angle`), else None.
        fusion_accel: there, the fusion window's mean of the rate's
            derivative [rad/s^2] (`Effect.fusion_gain`), else None.
        fusion_plain: there, the side angle of the fusion alone [rad],
            without the zero reading's edge anchors (for an effect that
            deflects the gyro from the resolver's side), else None.
        torque_angle: there, the angle a torque of the angle reads [rad]
            (`isp_twin.identification.side_angle.with_side_angle`), else None.
        gyro_error_fused: whether the angle fusion may correct the reading
            for a gyro error it measures against the angle (False where the
            runs of one command disagree on it,
            `isp_twin.identification.gyro_error.one_gyro_error`).
    """

    name: str
    t: np.ndarray
    u: np.ndarray
    omega: np.ndarray
    angle: np.ndarray
    source: Path | None
    dt: float
    resolver: np.ndarray | None = None
    fusion_accel: np.ndarray | None = None
    fusion_plain: np.ndarray | None = None
    torque_angle: np.ndarray | None = None
    gyro_error_fused: bool = True

    def __len__(self) -> int:
        return int(self.t.shape[0])


# ------------------------------------------------------------ derivations


def differentiate_angle(
    angle: np.ndarray, dt: float, window: int = DERIVATIVE_WINDOW
) -> np.ndarray:
    """Rate from an angle by a centred Savitzky-Golay derivative (no lag).

    Args:
        angle: shape (N,), any angle unit.
        dt: sample period [s].
        window: odd window length [samples]; shrunk for short records.

    Returns:
        rate, shape (N,), angle unit per second.
    """
    from scipy.signal import savgol_filter

    n = angle.shape[0]
    window = min(window, n if n % 2 else n - 1)
    if window < 3:
        return np.gradient(angle, dt)
    return savgol_filter(angle, window, polyorder=2, deriv=1, delta=dt, mode="interp")


def integrate_rate(omega: np.ndarray, dt: float, angle0: float = 0.0) -> np.ndarray:
    """Angle from a rate with the axis model's rule ``y[k] = y[k-1] + dt*w[k]``."""
    angle = angle0 + dt * np.cumsum(omega)
    return angle - dt * omega[0]


# ------------------------------------------------------------ mappings


def _unit_or_scale(signal: str, text: str, where: str) -> float:
    units = UNIT_FACTORS[signal]
    if text in units:
        return units[text]
    try:
        value = float(text)
    except ValueError:
        allowed = ", ".join(units) if units else "none"
        raise DataError(
            f"{where}: '{text}' is neither a number nor a unit of {signal} (units: {allowed})"
        ) from None
    if not math.isfinite(value) or value == 0.0:
        raise DataError(f"{where}: scale must be finite and non-zero, got {text}")
    return value


def parse_map_option(text: str) -> tuple[str, ColumnSpec, str | None]:
    """Parse one ``--map KEY=SOURCE[*SCALE]`` option.

    SOURCE is a CSV column name, a ``.mat`` variable, or ``VARIABLE:INDEX``
    (0-based column of a ``.mat`` matrix); SCALE is a number or a unit name
    of the signal (``rad/s``, ``rad``, ``ms``...), meaning "the file is in
    this unit".

    Returns:
        (canonical name, column spec, matrix variable or None).
    """
    where = f"--map {text}"
    if "=" not in text:
        raise DataError(f"{where}: expected KEY=SOURCE[*SCALE], KEY one of {', '.join(SIGNALS)}")
    key, rhs = (s.strip() for s in text.split("=", 1))
    if key not in SIGNALS:
        raise DataError(
            f"{where}: unknown signal '{key}'{nearest(key, SIGNALS)}; allowed: {', '.join(SIGNALS)}"
        )
    scale = 1.0
    if "*" in rhs:
        rhs, scale_text = (s.strip() for s in rhs.rsplit("*", 1))
        scale = _unit_or_scale(key, scale_text, where)
    variable = None
    source: str | int = rhs
    if ":" in rhs:
        variable, index = rhs.rsplit(":", 1)
        try:
            source = int(index)
        except ValueError:
            raise DataError(f"{where}: column index '{index}' is not an integer") from None
    if source == "":
        raise DataError(f"{where}: empty source")
    return key, ColumnSpec(source, scale), variable


def mapping_from_options(options: Sequence[str], initial_angle_deg: float = 0.0) -> DataMapping:
    """A `DataMapping` from several ``--map`` options (see `parse_map_option`)."""
    columns: dict[str, ColumnSpec] = {}
    variable = None
    for text in options:
        key, spec, var = parse_map_option(text)
        if var is not None:
            if variable is not None and var != variable:
                raise DataError(
                    f"--map {text}: all indexed columns must come from one matrix, "
                    f"got '{variable}' and '{var}'"
                )
            variable = var
        columns[key] = spec
    return DataMapping(columns=columns, variable=variable, initial_angle_deg=initial_angle_deg)


def load_data_description(path: str | Path) -> DataMapping:
    """Load a YAML data description (format in the module docstring)."""
    path = Path(path)
    raw, _ = load_yaml(path, "data description", DataError)
    top = ("variable", "columns", "initial_angle_deg")
    if not isinstance(raw, Mapping) or "columns" not in raw:
        raise DataError(f"{path}: expected a mapping with a 'columns' key")
    for k in raw:
        if k not in top:
            raise DataError(
                f"{path}: {k}: unknown key{nearest(str(k), top)}; allowed: {', '.join(top)}"
            )
    cols = raw["columns"]
    if not isinstance(cols, Mapping):
        raise DataError(f"{path}: columns: expected a mapping")
    columns = {}
    for key, entry in cols.items():
        where = f"{path}: columns.{key}"
        if key not in SIGNALS:
            raise DataError(
                f"{where}: unknown signal{nearest(str(key), SIGNALS)}; allowed: {', '.join(SIGNALS)}"
            )
        if isinstance(entry, Mapping):
            allowed = ("column", "scale", "unit")
            for k in entry:
                if k not in allowed:
                    raise DataError(f"{where}.{k}: unknown key; allowed: {', '.join(allowed)}")
            if "column" not in entry:
                raise DataError(f"{where}.column: missing")
            source = entry["column"]
            scale = 1.0
            if "unit" in entry:
                scale *= _unit_or_scale(key, str(entry["unit"]), f"{where}.unit")
            if "scale" in entry:
                scale *= _unit_or_scale(key, str(entry["scale"]), f"{where}.scale")
        else:
            source, scale = entry, 1.0
        if isinstance(source, bool) or not isinstance(source, (str, int)):
            raise DataError(f"{where}: expected a column name or index, got {source!r}")
        columns[key] = ColumnSpec(source, scale)
    angle0 = raw.get("initial_angle_deg", 0.0)
    if isinstance(angle0, bool) or not isinstance(angle0, (int, float)):
        raise DataError(f"{path}: initial_angle_deg: expected a number, got {angle0!r}")
    variable = raw.get("variable")
    return DataMapping(
        columns=columns,
        variable=None if variable is None else str(variable),
        initial_angle_deg=float(angle0),
        origin=str(path),
    )


# ------------------------------------------------------------ reading


def _read_csv(path: Path) -> tuple[list[str], np.ndarray]:
    """Header names and the numeric table (rows, cols) of a CSV file."""
    text = read_text(path, "data file", DataError)
    lines = text.splitlines(keepends=True)
    rows = list(csv.reader(line for line in lines if not line.startswith("#")))
    rows = [r for r in rows if r and any(c.strip() for c in r)]
    if not rows:
        raise DataError(f"{path}: empty file (expected a header row {','.join(SIGNALS)})")
    header = [h.strip() for h in rows[0]]
    table = np.empty((len(rows) - 1, len(header)))
    for i, row in enumerate(rows[1:]):
        line = i + 2  # 1-based, after the header
        if len(row) != len(header):
            raise DataError(f"{path}: row {line}: {len(row)} fields, header has {len(header)}")
        for j, cell in enumerate(row):
            try:
                table[i, j] = float(cell)
            except ValueError:
                raise DataError(
                    f"{path}: row {line}, column '{header[j]}': not a number: {cell.strip()!r}"
                ) from None
    return header, table


def _csv_columns(
    path: Path, mapping: DataMapping | None
) -> tuple[dict[str, np.ndarray], dict[str, str], int]:
    """Canonical signals (canonical units) from a CSV, their names, the header offset."""
    header, table = _read_csv(path)
    if mapping is None or not mapping.columns:
        mapping = DataMapping(
            columns={s: ColumnSpec(s) for s in SIGNALS if s in header}, origin="canonical columns"
        )
        for s in ("t", "u"):
            if s not in header:
                raise DataError(
                    f"{path}: missing column '{s}'{nearest(s, header)}; has {', '.join(header)}; "
                    f"needs t, u and omega and/or theta (or give a mapping)"
                )
    out, names = {}, {}
    for key, spec in mapping.columns.items():
        src = spec.source
        if isinstance(src, int):
            if not 0 <= src < len(header):
                raise DataError(
                    f"{path}: {mapping.origin}: {key} -> column index {src} does not exist "
                    f"(the file has {len(header)} columns)"
                )
            j = src
        else:
            if src not in header:
                raise DataError(
                    f"{path}: {mapping.origin}: {key} -> column '{src}' does not exist"
                    f"{nearest(src, header)}; has {', '.join(header)}"
                )
            j = header.index(src)
        out[key] = table[:, j] * spec.scale
        names[key] = f"column '{header[j]}'"
    return out, names, 2


def _mat_columns(
    path: Path, mapping: DataMapping | None
) -> tuple[dict[str, np.ndarray], dict[str, str], int]:
    from scipy.io import loadmat

    if mapping is None or not mapping.columns:
        raise DataError(
            f"{path}: a .mat file needs a mapping (--map t=VAR:0 ... or --describe FILE.yaml)"
        )
    try:
        mat = loadmat(str(path))
    except Exception as exc:  # scipy raises several types for a broken file
        raise DataError(f"{path}: cannot read as a MATLAB file ({exc})") from None
    variables = sorted(k for k in mat if not k.startswith("__"))
    out, names = {}, {}
    for key, spec in mapping.columns.items():
        src = spec.source
        if isinstance(src, int):
            var = mapping.variable
            if var is None:
                raise DataError(
                    f"{path}: {mapping.origin}: {key} -> column {src} needs a matrix variable "
                    f"(VAR:{src}); variables: {', '.join(variables)}"
                )
            if var not in mat:
                raise DataError(
                    f"{path}: {mapping.origin}: variable '{var}' does not exist"
                    f"{nearest(var, variables)}; has {', '.join(variables)}"
                )
            m = np.asarray(mat[var])
            if m.ndim != 2 or not np.issubdtype(m.dtype, np.number):
                raise DataError(
                    f"{path}: variable '{var}' is not a numeric matrix (shape {m.shape})"
                )
            if not 0 <= src < m.shape[1]:
                raise DataError(
                    f"{path}: {mapping.origin}: {key} -> column {src} of '{var}' does not exist "
                    f"('{var}' has {m.shape[1]} columns, 0..{m.shape[1] - 1})"
                )
            col = m[:, src]
            names[key] = f"{var}[:, {src}]"
        else:
            if src not in mat:
                raise DataError(
                    f"{path}: {mapping.origin}: {key} -> variable '{src}' does not exist"
                    f"{nearest(src, variables)}; has {', '.join(variables)}"
                )
            m = np.asarray(mat[src])
            if m.ndim != 2 or 1 not in m.shape or not np.issubdtype(m.dtype, np.number):
                raise DataError(
                    f"{path}: variable '{src}' has shape {m.shape}; a vector is needed "
                    f"(for a matrix use {src}:INDEX)"
                )
            col = m.ravel()
            names[key] = f"variable '{src}'"
        out[key] = np.asarray(col, dtype=float) * spec.scale
    return out, names, 0


def _check(
    path: Path, signals: dict[str, np.ndarray], names: dict[str, str], first_row: int
) -> float:
    """Validate the canonical signals; return the sample period [s]."""
    lengths = {k: v.shape[0] for k, v in signals.items()}
    if len(set(lengths.values())) > 1:
        raise DataError(f"{path}: signals differ in length: {lengths}")
    n = next(iter(lengths.values()))
    if n < MIN_SAMPLES:
        raise DataError(f"{path}: too few samples: {n} (at least {MIN_SAMPLES} needed)")
    row_word = "row" if first_row else "index"
    for key, v in signals.items():
        bad = np.flatnonzero(~np.isfinite(v))
        if bad.size:
            raise DataError(
                f"{path}: {row_word} {bad[0] + first_row}, {names[key]} ({key}): "
                f"{v[bad[0]]} (NaN or inf; {bad.size} such value(s))"
            )
    t = signals["t"]
    steps = np.diff(t)
    bad = np.flatnonzero(steps <= 0)
    if bad.size:
        k = bad[0] + 1
        raise DataError(
            f"{path}: {row_word} {k + first_row}, {names['t']} (t): time not strictly increasing "
            f"({t[k - 1]:.9g} s then {t[k]:.9g} s)"
        )
    dt = float(np.median(steps))
    dev = np.abs(steps - dt) / dt
    k = int(np.argmax(dev))
    if dev[k] > UNIFORM_TOLERANCE:
        raise DataError(
            f"{path}: {row_word} {k + 1 + first_row}, {names['t']} (t): time base not uniform: "
            f"step {steps[k]:.6g} s vs median {dt:.6g} s ({100 * dev[k]:.3g} % off, "
            f"{UNIFORM_TOLERANCE:.0%} allowed)"
        )
    return dt


def load_measured(path: str | Path, mapping: DataMapping | None = None) -> MeasuredData:
    """Load one open-loop run (canonical CSV, or CSV/.mat through a mapping).

    Args:
        path: a ``.csv`` or ``.mat`` file.
        mapping: how the file's columns map to t/u/omega/theta; None for a
            canonical CSV.

    Raises:
        ResourceNotFound: the file does not exist.
        DataError: unreadable file, missing column, NaN/inf, bad time base,
            too few samples; the message names the file and the row/column.
    """
    path = Path(path)
    if path.is_dir():
        raise DataError(f"{path}: is a directory, expected a data file")
    if not path.is_file():
        raise ResourceNotFound(f"{path}: data file not found")
    if mapping is not None and mapping.columns:
        for s in ("t", "u"):
            if s not in mapping.columns:
                raise DataError(
                    f"{path}: {mapping.origin}: no source for '{s}' (needs t, u and omega and/or theta)"
                )
    if path.suffix.lower() == ".mat":
        signals, names, first_row = _mat_columns(path, mapping)
    else:
        signals, names, first_row = _csv_columns(path, mapping)
    if "omega" not in signals and "theta" not in signals:
        raise DataError(
            f"{path}: needs a rate column 'omega' [deg/s] or an angle column 'theta' [deg] (or both)"
        )
    dt = _check(path, signals, names, first_row)
    angle0 = (mapping.initial_angle_deg if mapping is not None else 0.0) * DEG
    if "theta" in signals:
        angle = signals["theta"] * DEG
    if "omega" in signals:
        omega = signals["omega"] * DEG
    else:
        omega = differentiate_angle(angle, dt)
    if "theta" not in signals:
        angle = integrate_rate(omega, dt, angle0)
    return MeasuredData(
        name=path.stem,
        t=signals["t"].copy(),
        u=signals["u"].copy(),
        omega=np.ascontiguousarray(omega),
        angle=np.ascontiguousarray(angle),
        source=path,
        dt=dt,
    )


def save_measured(data: MeasuredData, path: str | Path) -> Path:
    """Write `data` as a canonical CSV (t s, u, omega deg/s, theta deg), atomically."""
    path = Path(path)
    table = np.column_stack([data.t, data.u, data.omega / DEG, data.angle / DEG])
    with staged_path(path) as tmp:
        np.savetxt(tmp, table, delimiter=",", header=",".join(SIGNALS), comments="", fmt="%.10g")
    return path


def check_sample_period(
    runs: Sequence[MeasuredData], sample_time_s: float, params_name: str
) -> list[str]:
    """Check each run's period against the parameters'; one report line per run.

    Raises:
        DataError: a run's period is more than `SAMPLE_PERIOD_TOLERANCE` off.
    """
    lines = []
    for d in runs:
        off = (d.dt - sample_time_s) / sample_time_s
        where = d.source if d.source is not None else d.name
        if abs(off) > SAMPLE_PERIOD_TOLERANCE:
            raise DataError(
                f"{where}: measured sample period {d.dt:.9g} s is {100 * off:+.3g} % off the "
                f"{sample_time_s:.9g} s of {params_name} ({SAMPLE_PERIOD_TOLERANCE:.0%} allowed; "
                "the parameters are per sample): resample the data"
            )
        lines.append(f"{d.name}: sample period {d.dt:.9g} s ({1e6 * off:+.0f} ppm)")
    return lines


def unique_names(runs: Sequence[MeasuredData]) -> list[MeasuredData]:
    """The runs, renamed where two share a name (the same file stem in two folders).

    Two different files with one name get their parent folder prepended
    (``paper2_eq7``), then a counter; one file given twice keeps its name.
    Report figures and per-run tables are keyed by name.
    """

    def key(d: MeasuredData) -> object:
        return Path(d.source).resolve() if d.source is not None else id(d)

    files: dict[str, set] = {}
    for d in runs:
        files.setdefault(d.name, set()).add(key(d))
    given: dict[object, str] = {}  # the same file given twice keeps one name
    taken: set[str] = set()
    out = []
    for d in runs:
        if key(d) not in given:
            name = d.name
            if len(files[name]) > 1 and d.source is not None:
                name = f"{Path(d.source).resolve().parent.name}_{name}"
            base, k = name, 2
            while name in taken:
                name, k = f"{base}_{k}", k + 1
            taken.add(name)
            given[key(d)] = name
        name = given[key(d)]
        out.append(d if name == d.name else replace(d, name=name))
    return out

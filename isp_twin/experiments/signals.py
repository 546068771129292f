"""The closed loop's signal table: one definition of what a run records, and where.

The closed loop (`isp_twin.experiments.closed_loop.ClosedLoop`) writes one row per 1 ms
sample into a buffer laid out by `CLOSED_LOOP_SIGNALS`; the metrics, the
recorder and the tests address the same series by name (``<axis>/<signal>``).
Units are SI (see each `Signal`), the amplifier command in digits.
"""

from __future__ import annotations

from dataclasses import dataclass

from isp_twin.vocabulary import GIMBAL_AXES, INNER_AXES, OUTER_AXES, TABLE_JOINTS

__all__ = [
    "Signal",
    "INNER_SIGNALS",
    "OUTER_SIGNALS",
    "SignalTable",
    "CLOSED_LOOP_SIGNALS",
    "signal_key",
]


@dataclass(frozen=True)
class Signal:
    """One per-axis signal.

    Attributes:
        name: short name, the part after ``<axis>/``.
        unit: its unit (SI, or ``digits`` / ``index``).
        doc: what it is.
    """

    name: str
    unit: str
    doc: str


#: Per inner axis (`INNER_AXES`), in buffer order.
INNER_SIGNALS: tuple[Signal, ...] = (
    Signal("omega_carrier", "rad/s", "carrier rate on the gimbal axis (omega of Eq. 10)"),
    Signal("omega_inertial", "rad/s", "true inertial rate omega_1"),
    Signal("omega_relative", "rad/s", "relative rate omega_2"),
    Signal("gyro", "rad/s", "the gyro reading (quantised, noisy)"),
    Signal("command", "digits", "amplifier command u"),
    Signal("friction", "N*m", "friction torque of the last step"),
    Signal("nfc", "digits", "NFC feed-forward u_c3 (Eq. 13)"),
    Signal("regime", "index", "friction regime 0 R+, 1 R-, 2 L+, 3 L-"),
)
#: Per outer axis (`OUTER_AXES`), in buffer order.
OUTER_SIGNALS: tuple[Signal, ...] = (
    Signal("follow_error", "rad", "true follow error (inner angle minus its centre)"),
    Signal("command", "digits", "follower command"),
)


def signal_key(axis: str, name: str) -> str:
    """The series name ``<axis>/<name>`` used by `RunResult.signals`."""
    return f"{axis}/{name}"


@dataclass(frozen=True)
class SignalTable:
    """Column layout of a run's per-sample buffer.

    Columns are the inner axes' `INNER_SIGNALS` blocks, then the outer axes'
    `OUTER_SIGNALS` blocks, then one joint angle per entry of `joints` [rad].

    Attributes:
        inner_axes: inner axes, in buffer order.
        outer_axes: outer axes, in buffer order.
        joints: joint names of the angle columns, in buffer order.
    """

    inner_axes: tuple[str, ...]
    outer_axes: tuple[str, ...]
    joints: tuple[str, ...]

    @property
    def signals(self) -> tuple[str, ...]:
        """Series names of the signal columns, in buffer order."""
        inner = [signal_key(a, s.name) for a in self.inner_axes for s in INNER_SIGNALS]
        outer = [signal_key(a, s.name) for a in self.outer_axes for s in OUTER_SIGNALS]
        return tuple(inner + outer)

    @property
    def width(self) -> int:
        """Columns of a buffer row."""
        return len(self.signals) + len(self.joints)

    def block(self, axis: str) -> slice:
        """The contiguous columns of one axis's signals."""
        if axis in self.inner_axes:
            i, n = self.inner_axes.index(axis), len(INNER_SIGNALS)
            return slice(n * i, n * i + n)
        base = len(self.inner_axes) * len(INNER_SIGNALS)
        i, n = self.outer_axes.index(axis), len(OUTER_SIGNALS)
        return slice(base + n * i, base + n * i + n)

    @property
    def joint_columns(self) -> slice:
        """The columns of the joint angles."""
        n = len(self.signals)
        return slice(n, n + len(self.joints))

    def unit(self, key: str) -> str:
        """Unit of a series name ``<axis>/<signal>``."""
        axis, name = key.split("/", 1)
        table = INNER_SIGNALS if axis in self.inner_axes else OUTER_SIGNALS
        return next(s.unit for s in table if s.name == name)


#: The closed loop's layout (joint angles: turntable, then the gimbals in the twin's order).
CLOSED_LOOP_SIGNALS = SignalTable(
    inner_axes=INNER_AXES,
    outer_axes=OUTER_AXES,
    joints=TABLE_JOINTS + GIMBAL_AXES,
)

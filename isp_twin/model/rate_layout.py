"""Layouts of the flat parameter vectors that the fits see.

The rate-form parameters of Eq. 6 travel through identification and
diagnosis as one flat vector: per regime, in Eq. 8's regime order, the
fields of `isp_twin.model.parameters.RateParams` (regime-major, so a regime's
fields are contiguous). `RateLayout` names that order once: its size, the
index of a (regime, field), a field's indices across the regimes (the static
levels a fit scans first), a regime's slice, and the ``(..., regimes,
fields)`` table view. The instance the package uses, built from the
vocabulary's `REGIMES` and `RateParams`' own field names, is
`isp_twin.model.parameters.RATE_LAYOUT`.

A diagnosis candidate's vector is the rate vector followed by one effect's
free parameters (`CandidateLayout`).

Only this module writes the vector's arithmetic (tests/test_rate_layout.py
fails on a ``reshape(4, 5)``-style literal elsewhere).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["RateLayout", "CandidateLayout"]


@dataclass(frozen=True)
class RateLayout:
    """The flat rate-parameter vector: regime-major, fields within a regime.

    Attributes:
        regimes: regime names in vector order (Eq. 8: R+, R-, L+, L-).
        fields: field names within a regime, in vector order.
    """

    regimes: tuple[str, ...]
    fields: tuple[str, ...]

    def __post_init__(self) -> None:
        for what, names in (("regimes", self.regimes), ("fields", self.fields)):
            if not names or len(set(names)) != len(names):
                raise ValueError(f"rate layout: {what} must be distinct and non-empty: {names}")

    @property
    def n_regimes(self) -> int:
        return len(self.regimes)

    @property
    def n_fields(self) -> int:
        return len(self.fields)

    @property
    def size(self) -> int:
        """Length of the flat vector."""
        return self.n_regimes * self.n_fields

    def regime_index(self, regime: str | int) -> int:
        """A regime's position, from its name or its index."""
        if isinstance(regime, str):
            return self.regimes.index(regime)
        if not 0 <= regime < self.n_regimes:
            raise IndexError(f"regime index {regime} outside 0..{self.n_regimes - 1}")
        return int(regime)

    def field_index(self, field: str) -> int:
        """A field's position within a regime."""
        return self.fields.index(field)

    def index(self, regime: str | int, field: str) -> int:
        """Position of (regime, field) in the flat vector."""
        return self.regime_index(regime) * self.n_fields + self.field_index(field)

    def regime_slice(self, regime: str | int) -> slice:
        """The flat vector's entries of one regime (all its fields)."""
        start = self.regime_index(regime) * self.n_fields
        return slice(start, start + self.n_fields)

    def field_indices(self, field: str) -> tuple[int, ...]:
        """Positions of one field in every regime, in regime order."""
        return tuple(self.index(r, field) for r in range(self.n_regimes))

    def regime_mask(self, per_regime: np.ndarray) -> np.ndarray:
        """Per-regime booleans (n_regimes,) -> a mask of the flat vector (size,)."""
        per_regime = np.asarray(per_regime, dtype=bool)
        if per_regime.shape != (self.n_regimes,):
            raise ValueError(
                f"regime mask: shape must be ({self.n_regimes},), got {per_regime.shape}"
            )
        return np.repeat(per_regime, self.n_fields)

    @property
    def static_indices(self) -> tuple[int, ...]:
        """Positions of the four static (breakaway) levels b·Ts."""
        return self.field_indices("static")

    def as_table(self, x: np.ndarray) -> np.ndarray:
        """Flat vectors (..., size) as a table (..., n_regimes, n_fields) (a view where numpy can)."""
        x = np.asarray(x)
        if x.shape[-1:] != (self.size,):
            raise ValueError(f"rate vector: last axis must be {self.size}, shape {x.shape}")
        return x.reshape(*x.shape[:-1], self.n_regimes, self.n_fields)

    def from_table(self, table: np.ndarray) -> np.ndarray:
        """Inverse of `as_table`: (..., n_regimes, n_fields) -> (..., size)."""
        table = np.asarray(table)
        if table.shape[-2:] != (self.n_regimes, self.n_fields):
            raise ValueError(
                f"rate table: last axes must be ({self.n_regimes}, {self.n_fields}), "
                f"shape {table.shape}"
            )
        return table.reshape(*table.shape[:-2], self.size)

    def column(self, x: np.ndarray, field: str) -> np.ndarray:
        """One field across the regimes: (..., size) -> (..., n_regimes)."""
        return self.as_table(x)[..., self.field_index(field)]

    def per_field(self, values: dict[str, float]) -> np.ndarray:
        """A flat vector holding ``values[field]`` in every regime, shape (size,)."""
        row = [values[f] for f in self.fields]
        return np.tile(np.asarray(row, dtype=float), self.n_regimes)

    def labels(self) -> list[str]:
        """``regime.field`` of every entry, in vector order (e.g. ``R+.gain``)."""
        return [f"{r}.{f}" for r in self.regimes for f in self.fields]


@dataclass(frozen=True)
class CandidateLayout:
    """A candidate's flat vector: the rate vector, then one effect's free parameters.

    Attributes:
        rate: the rate part's layout.
        effect_params: the effect's free parameter names, in vector order
            (empty for the model without an effect).
    """

    rate: RateLayout
    effect_params: tuple[str, ...] = ()

    @property
    def size(self) -> int:
        return self.rate.size + len(self.effect_params)

    @property
    def effect_slice(self) -> slice:
        """The effect part of the flat vector."""
        return slice(self.rate.size, self.size)

    def effect_index(self, name: str) -> int:
        """Position of an effect parameter in the flat vector."""
        return self.rate.size + self.effect_params.index(name)

    def rate_part(self, x: np.ndarray) -> np.ndarray:
        """The rate parameters of (..., size) vectors: (..., rate.size)."""
        return np.asarray(x)[..., : self.rate.size]

    def effect_values(self, x: np.ndarray) -> dict[str, np.ndarray]:
        """Effect parameter name -> its entries of (..., size) vectors, shape (...)."""
        x = np.asarray(x)
        return {p: x[..., self.rate.size + j] for j, p in enumerate(self.effect_params)}

    def split(self, x: np.ndarray) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """(rate part, effect values) of (..., size) vectors."""
        return self.rate_part(x), self.effect_values(x)

"""The shape every catalogue effect shares: an id, parameters with units, an observability
condition, a model extension, and one sentence of physics.

Extensions come in four kinds (:data:`EffectKind`), and each effect says whether its physics
is the table's (``needs_table``: never a candidate on a recording without one):

- ``columns``: the effect adds A θ to the stacked window means (linear in its parameters θ
  to first order, the columns evaluated at the current scale matrix K);
- ``variance``: the effect adds a random term per window (``pose_error``), tested as a
  variance component;
- ``window``: the effect is tested within each window's own samples (``settling``), not on
  the window means;
- ``motion``: the effect needs the table to turn while the sensor is recorded; a static
  diagnosis reports it as not observable (a moving recording's dynamic model fits it).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Literal, Protocol

import numpy as np
import numpy.typing as npt

from bench.diagnosis.evidence import StaticEvidence
from bench.diagnosis.thresholds import THRESHOLDS, Thresholds

FloatArray = npt.NDArray[np.float64]

EffectKind = Literal["columns", "variance", "window", "motion"]
"""How an effect enters the model (module docstring)."""


@dataclass(frozen=True)
class ParamSpec:
    """One parameter of an effect: contract name, unit, shape (−1: one per window or axis)."""

    name: str
    unit: str
    shape: tuple[int, ...]


@dataclass(frozen=True)
class Candidate:
    """One way of adding (part of) an effect to the model.

    :param effect: catalogue id.
    :param label: e.g. ``nonlinearity_quadratic[z]``.
    :param channels: the raw channels the candidate acts on (0, 1, 2).
    :param columns: (evidence, K (3, 3)) -> (3m, q) design columns.
    :param names: q names of the coefficients, for messages.
    :param to_parameters: (θ (q,), cov (q, q), K) -> ({name: value}, {name: sigma}) in contract form.
    :param extra_params: parameters found by a search rather than fitted as columns (a profiled
        time constant): charged in the BIC beside the q columns.
    :param tries: the effective number of independent candidates the search behind it tried
        (``profiled.resolve``, Davies' bound): its gate is at α / tries; 1 for fixed columns.
    :param family: a one-parameter family whose parameter is still to be profiled (the
        selection resolves it into a fixed candidate first), or ``None``.
    :param resolved_from: the family a fixed candidate was resolved from (profiled again under
        the final noise before the model is reported, ``profiled.reprofiled``), or ``None``.
    """

    effect: str
    label: str
    channels: tuple[int, ...]
    columns: Callable[[StaticEvidence, FloatArray], FloatArray]
    names: tuple[str, ...]
    to_parameters: Callable[[FloatArray, FloatArray, FloatArray], tuple[dict[str, Any], dict[str, Any]]]
    extra_params: int = 0
    tries: float = 1.0
    family: Family | None = None
    resolved_from: Family | None = None


@dataclass(frozen=True)
class Family:
    """A candidate with one column a(v) that depends on a parameter v not linear in the model
    (a time constant): profiled on ``grid`` by the selection (``profiled.resolve``).

    :param grid: (G,) values of v searched, ascending.
    :param column: (evidence, K, v) -> (3m, 1) the column at v.
    :param null_column: (evidence, K) -> (3m, 1) the column at the value where the family
        reduces to the effect ``reduces_to`` (a lag of 0: the plain temperature coefficient).
    :param at: (v̂, inflation, v_per_coef) -> the fixed candidate at v̂; ``inflation`` is the
        ratio of the coefficient's variance with v free to its variance at v̂ held, and
        ``v_per_coef`` is σ_v·|c| / σ_c (v held), both from the joint information at v̂, so
        that the fitted candidate reports σ_c and σ_v = σ_c(v held)·v_per_coef / |c|.
    :param reduces_to: the effect id the family reduces to at ``null_column``.
    """

    grid: tuple[float, ...]
    column: Callable[[StaticEvidence, FloatArray, float], FloatArray]
    null_column: Callable[[StaticEvidence, FloatArray], FloatArray]
    at: Callable[[float, float, float], Candidate]
    reduces_to: str


class Effect(Protocol):
    """A catalogue effect (``docs/cli-contract.md``); implementations are frozen dataclasses."""

    @property
    def id(self) -> str:
        """The contract's effect id."""
        ...

    @property
    def kind(self) -> EffectKind:
        """How the effect enters the model: columns, variance, window or motion."""
        ...

    @property
    def needs_table(self) -> bool:
        """Whether its physics is the table's (its motion, encoders, base or ringing after a move)."""
        ...

    @property
    def parameters(self) -> tuple[ParamSpec, ...]:
        """The contract's parameter names with units."""
        ...

    @property
    def explanation(self) -> str:
        """One sentence of physics."""
        ...

    def observable(self, ev: StaticEvidence, th: Thresholds = THRESHOLDS) -> tuple[bool, str]:
        """Whether the recording can show the effect (under the knobs ``th``), and why (not)."""
        ...

    def candidates(self, ev: StaticEvidence, th: Thresholds = THRESHOLDS) -> list[Candidate]:
        """The model extensions to try (``columns`` kind; empty otherwise)."""
        ...


AXES = "xyz"


def leverage(X: FloatArray, cols: FloatArray, basis: FloatArray | None = None) -> FloatArray:
    """(q,) fraction of each column's norm outside the span of X (0: indistinguishable).

    :param X: (n, p) design; :param cols: (n, q) columns.
    :param basis: (n, p) ``np.linalg.qr(X)[0]`` when already known (a caller that tries many
        columns against one design factors it once).
    """
    Q = np.linalg.qr(X)[0] if basis is None else basis
    out = []
    for c in cols.T:
        nrm = float(np.linalg.norm(c))
        out.append(0.0 if nrm == 0 else float(np.linalg.norm(c - Q @ (Q.T @ c)) / nrm))
    return np.array(out)


def first_order_design(f_m_s2: FloatArray) -> FloatArray:
    """(3m, 12) stacked design of raw = b + K f: columns b_x, b_y, b_z, K_xx … K_zz."""
    m = f_m_s2.shape[0]
    X = np.zeros((3 * m, 12))
    for i in range(3):
        X[i::3, i] = 1.0
        X[i::3, 3 + 3 * i : 6 + 3 * i] = f_m_s2
    return X


def channel_column(ev: StaticEvidence, i: int, values: FloatArray) -> FloatArray:
    """(3m, q) columns acting on channel i only; ``values`` (m,) or (m, q)."""
    v = values[:, None] if values.ndim == 1 else values
    out = np.zeros((ev.n_obs, v.shape[1]))
    out[i::3] = v
    return out

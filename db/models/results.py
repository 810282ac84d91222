"""What a run produces: fitted models, diagnosis findings, certificates, drift checks."""

from __future__ import annotations

import datetime as dt
from typing import Any

import numpy as np
import numpy.typing as npt
import sqlalchemy as sa
from sqlalchemy.orm import Mapped, mapped_column, relationship

from bench.fit_kind import FitKind
from db.base import Base, IntId
from db.models._enum import value_enum
from db.models.runs import Run
from db.models.units import Unit
from db.types import NpyArray, utc_now


class FitModel(IntId, Base):
    """A fitted sensor model.

    :param contract: the ``calbench calibrate --json`` object (``docs/cli-contract.md``):
        bias, scale_matrix, their sigmas, terms, extra, residual_rms, g_check.
    :param param_names: names of the parameters in the order of ``covariance``'s rows.
    :param covariance: (n_params, n_params) covariance of the fitted parameters, in the
        units of ``contract`` (stored as ``.npy`` bytes), or ``None``.
    """

    __tablename__ = "fit_model"

    run_id: Mapped[str] = mapped_column(
        sa.String(64), sa.ForeignKey("run.id", ondelete="CASCADE"), index=True
    )
    kind: Mapped[FitKind] = mapped_column(value_enum(FitKind, "fit_kind"))
    contract: Mapped[dict[str, Any]]
    param_names: Mapped[list[Any]] = mapped_column(default=list)
    covariance: Mapped[npt.NDArray[np.float64] | None] = mapped_column(NpyArray())

    run: Mapped[Run] = relationship(lazy="raise")


class Finding(IntId, Base):
    """One finding of ``calbench diagnose``: an effect id of the catalogue and its fit.

    :param parameters, sigma: the effect's parameters and their 1-sigma uncertainties,
        keyed by the parameter names of ``docs/cli-contract.md``.
    :param delta_bic: BIC change from adding the effect (negative: the effect is supported).
    """

    __tablename__ = "finding"

    run_id: Mapped[str] = mapped_column(
        sa.String(64), sa.ForeignKey("run.id", ondelete="CASCADE"), index=True
    )
    effect: Mapped[str] = mapped_column(sa.String(64))
    summary: Mapped[str] = mapped_column(sa.Text)
    parameters: Mapped[dict[str, Any]] = mapped_column(default=dict)
    sigma: Mapped[dict[str, Any]] = mapped_column(default=dict)
    delta_bic: Mapped[float | None]
    residual_rms_after: Mapped[float | None]

    run: Mapped[Run] = relationship(lazy="raise")


class Certificate(IntId, Base):
    """An issued calibration certificate.

    The number is ``CB-<year>-<serial:05d>``: ``(year, serial)`` is unique, and the issuer
    retries on a conflict, so two benches issuing at once never share a number.

    :param content: the certificate's JSON content (ISO/IEC 17025 7.8 fields).
    :param sha256: hex SHA-256 of the canonical JSON of ``content``.
    :param pdf: the rendered PDF, or ``None``.
    """

    __tablename__ = "certificate"
    __table_args__ = (sa.UniqueConstraint("year", "serial"),)

    run_id: Mapped[str] = mapped_column(
        sa.String(64), sa.ForeignKey("run.id", ondelete="RESTRICT"), index=True
    )
    unit_id: Mapped[int] = mapped_column(sa.ForeignKey("unit.id", ondelete="RESTRICT"), index=True)
    year: Mapped[int]
    serial: Mapped[int]
    number: Mapped[str] = mapped_column(sa.String(32), unique=True)
    content: Mapped[dict[str, Any]]
    sha256: Mapped[str] = mapped_column(sa.String(64))
    pdf: Mapped[bytes | None] = mapped_column(sa.LargeBinary)
    issued_at: Mapped[dt.datetime] = mapped_column(default=utc_now)

    run: Mapped[Run] = relationship(lazy="raise")
    unit: Mapped[Unit] = relationship(lazy="raise")


class DriftCheck(IntId, Base):
    """A re-measurement of a unit compared with its reference certificate.

    :param result: per-parameter differences and their combined uncertainties (JSON).
    :param flagged: the unit moved beyond what the uncertainties allow.
    """

    __tablename__ = "drift_check"

    unit_id: Mapped[int] = mapped_column(sa.ForeignKey("unit.id", ondelete="CASCADE"), index=True)
    run_id: Mapped[str | None] = mapped_column(
        sa.String(64), sa.ForeignKey("run.id", ondelete="SET NULL"), index=True
    )
    reference_certificate_id: Mapped[int | None] = mapped_column(
        sa.ForeignKey("certificate.id", ondelete="SET NULL"), index=True
    )
    result: Mapped[dict[str, Any]] = mapped_column(default=dict)
    flagged: Mapped[bool] = mapped_column(sa.Boolean(create_constraint=True, name="flagged_bool"))
    checked_at: Mapped[dt.datetime] = mapped_column(default=utc_now)

    unit: Mapped[Unit] = relationship(lazy="raise")
    run: Mapped[Run | None] = relationship(lazy="raise")
    reference_certificate: Mapped[Certificate | None] = relationship(lazy="raise")

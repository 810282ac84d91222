"""UtcDateTime and NpyArray: round trips and refusals, on SQLite and PostgreSQL."""

from __future__ import annotations

import datetime as dt

import numpy as np
import pytest
import sqlalchemy as sa
from sqlalchemy.exc import StatementError

from bench.fit_kind import FitKind
from db.models import Bench
from db.repo.results import add_fit
from db.types import NpyArray, UtcDateTime
from tests.db._factories import make_run


def test_naive_datetime_refused_at_bind(db_session_factory):
    with pytest.raises(StatementError, match="naive datetime"), db_session_factory.begin() as s:
        s.add(Bench(name="b", created_at=dt.datetime(2025, 1, 1, 12, 0)))
        s.flush()


def test_aware_datetime_comes_back_as_same_instant_in_utc(db_session_factory):
    plus_two = dt.timezone(dt.timedelta(hours=2))
    when = dt.datetime(2025, 3, 4, 14, 30, 15, 123456, tzinfo=plus_two)
    with db_session_factory.begin() as s:
        s.add(Bench(name="b", created_at=when))
    with db_session_factory() as s:
        got = s.scalars(sa.select(Bench.created_at)).one()
    assert got.tzinfo is not None and got.utcoffset() == dt.timedelta(0)
    assert got == when
    assert got.hour == 12  # 14:30 at +02:00 is 12:30 UTC


def test_server_default_timestamp_is_aware(db_session_factory):
    with db_session_factory.begin() as s:
        s.execute(sa.insert(Bench.__table__).values(name="raw"))  # server default, not the Python one
    with db_session_factory() as s:
        got = s.scalars(sa.select(Bench.created_at)).one()
    assert got.tzinfo is not None
    assert abs((dt.datetime.now(dt.UTC) - got).total_seconds()) < 3600


def test_utc_type_refuses_non_datetime():
    with pytest.raises(TypeError):
        UtcDateTime().process_bind_param("2025-01-01", sa.create_engine("sqlite://").dialect)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    "arr",
    [
        np.arange(12, dtype=np.float64).reshape(3, 4) * 1e-7,
        np.array([[1.0, np.nan], [np.inf, -0.0]]),
        np.arange(5, dtype=np.int32),
        np.zeros((0, 3)),
    ],
)
def test_npy_array_round_trip_keeps_shape_dtype_values(db_session_factory, arr):
    with db_session_factory.begin() as s:
        run = make_run(s)
        fit_id = add_fit(s, run.id, FitKind.STATIC, {"bias": [0, 0, 0]}).id
        s.execute(
            sa.text("UPDATE fit_model SET covariance = :c WHERE id = :i").bindparams(
                sa.bindparam("c", type_=NpyArray())
            ),
            {"c": arr, "i": fit_id},
        )
    with db_session_factory() as s:
        got = s.execute(
            sa.text("SELECT covariance FROM fit_model").columns(covariance=NpyArray())
        ).scalar_one()
    assert got.shape == arr.shape and got.dtype == arr.dtype
    np.testing.assert_array_equal(got, arr)


def test_npy_array_refuses_object_arrays():
    with pytest.raises(ValueError, match="object"):
        NpyArray().process_bind_param(
            np.array([{"a": 1}], dtype=object), sa.create_engine("sqlite://").dialect
        )

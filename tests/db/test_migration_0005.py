"""Migration 0005 on a database made at revision 0004: the fit, the diagnosis, its notes and the
sample gaps leave ``params`` for their typed homes, on SQLite and on PostgreSQL; what a run's
REST object shows is what ``params`` held; the downgrade gives the same ``params`` back and
drops no row of another table."""

from __future__ import annotations

import copy
import dataclasses
from typing import Any

import numpy as np
import sqlalchemy as sa
from sqlalchemy.engine import Engine

from db.engine import make_session_factory
from db.migrate import current_revision, downgrade, upgrade
from db.types import NpyArray
from tests.db.old_schema import SETUP, at_revision, row_counts, run_table

# the tables as revision 0004 has them (not the models: they follow the newest revision)
RUN = run_table(
    sa.column("outcome", sa.String),
    sa.column("n_samples", sa.BigInteger),
    sa.column("kind", sa.String),
)
FIT = sa.table(
    "fit_model",
    sa.column("id", sa.Integer),
    sa.column("run_id", sa.String),
    sa.column("kind", sa.String),
    sa.column("contract", sa.JSON),
    sa.column("param_names", sa.JSON),
    sa.column("covariance", NpyArray()),
)
FINDING = sa.table(
    "finding",
    sa.column("run_id", sa.String),
    sa.column("effect", sa.String),
    sa.column("summary", sa.Text),
    sa.column("parameters", sa.JSON),
    sa.column("sigma", sa.JSON),
    sa.column("delta_bic", sa.Float),
)
WINDOW = sa.table(
    "run_window",
    sa.column("run_id", sa.String),
    sa.column("index", sa.Integer),
    sa.column("label", sa.String),
    sa.column("kind", sa.String),
    sa.column("start_s", sa.Float),
    sa.column("end_s", sa.Float),
    sa.column("n_samples", sa.Integer),
    sa.column("pose_deg", sa.JSON),
    sa.column("means", sa.JSON),
)

CONTRACT: dict[str, Any] = {
    "unit": "SN-1",
    "channel_unit": "m/s^2",
    "procedure": "static-12",
    "bias": [0.01, -0.02, 0.03],
    "bias_sigma": [1e-4, 1e-4, 1e-4],
    "scale_matrix": [[1.001, 0.0, 0.0], [0.002, 0.999, 0.0], [0.0, 0.001, 1.0]],
    "scale_matrix_sigma": [[1e-4] * 3] * 3,
    "terms": ["bias", "scale_matrix"],
    "extra": {},
    "residual_rms": 0.0012,
    "g_check": {"after": {"mean_m_s2": 9.80665, "std_m_s2": 0.0004, "max_abs_dev_m_s2": 0.001}},
    "dof": 24,
    "zero_redundancy": False,
    "unused_windows": [],
    "warnings": [],
    "bias_reference": "run_mean",
}
BEFORE = {"mean_m_s2": 9.79, "std_m_s2": 0.01, "max_abs_dev_m_s2": 0.02}
DYNAMIC = {**CONTRACT, "procedure": "rate-1axis", "method": "dynamic-batch", "extra": {"time_skew_s": 1e-4}}
SCALAR = {**CONTRACT, "procedure": "hand-held", "terms": ["bias", "scale_matrix_lower_triangular"], "dof": 3}
"""An orientation-free fit's object: its terms say so (docs/cli-contract.md), it has no method."""
COV = np.diag(np.arange(1.0, 13.0)) * 1e-8
NAMES = [f"p{i}" for i in range(12)]
GAPS: list[dict[str, Any]] = [
    {
        "first_lost_seq": 4410,
        "n_lost": 7,
        "cause": "dropped",
        "after_row": 4410,
        "t_last_s": 44.09,
        "t_resume_s": 44.17,
        "window_index": 3,
        "window_label": "pose 3",
        "action": "window re-measured",
        "daq_epoch": 0,
    },
    {
        "first_lost_seq": None,
        "n_lost": None,
        "cause": "restart",
        "after_row": 9001,
        "t_last_s": None,
        "t_resume_s": 90.5,
        "window_index": None,
        "window_label": "",
        "action": "between windows",
        "daq_epoch": 1,
    },
]
FINDING_ROW = {
    "effect": "nonlinearity_quadratic",
    "summary": "k2 = 1e-4 /g",
    "parameters": {"k2_per_g": [1e-4, 0.0, 0.0]},
    "sigma": {"k2_per_g": [1e-5, 1e-5, 1e-5]},
    "delta_bic": -25.0,
}
DIAGNOSIS = {"findings": [{**FINDING_ROW, "residual_rms_after": 0.001}], "baseline_rms": 0.0012}
NO_LIMITS = "no conformity statement: the unit's model has no limits"
REFUSED = "no certificate issued for run R-FREE from a real bench: the laboratory is a placeholder"
NOT_DIAGNOSED = "diagnosis not performed: recording /data/R-FREE.csv cannot be read"


@dataclasses.dataclass(frozen=True)
class Case:
    """A run at 0004 and what 0005 makes of it."""

    state: str
    params: dict[str, Any]
    rows: tuple[dict[str, Any], ...] = ()
    """its ``fit_model`` rows at 0004 (oldest first)"""
    n_samples: int | None = 9600
    fits: tuple[tuple[str, dict[str, Any]], ...] = ()
    """(kind, contract) of its ``fit_model`` rows at 0005"""
    columns: dict[str, Any] = dataclasses.field(default_factory=dict)
    gaps: tuple[dict[str, Any], ...] = ()
    kept: tuple[str, ...] = ()
    """keys whose value does not fit its home and stays in params"""
    rows_after_downgrade: int | None = None


CASES = {
    # a service calibration: the fit (twice), the diagnosis, two gaps
    "R-DONE": Case(
        "completed",
        {
            **SETUP,
            "calibration": CONTRACT,
            "diagnosis": DIAGNOSIS,
            "diagnosis_error": None,
            "sample_gaps": GAPS,
        },
        rows=({"kind": "static", "contract": CONTRACT, "param_names": NAMES, "covariance": COV},),
        fits=(("static", CONTRACT),),
        columns={"diagnosis": DIAGNOSIS},
        gaps=tuple(GAPS),
    ),
    # completed without limits, refused a certificate, not diagnosed, no gap
    "R-FREE": Case(
        "completed",
        {
            **SETUP,
            "calibration": CONTRACT,
            "diagnosis_error": NOT_DIAGNOSED,
            "conformity_note": NO_LIMITS,
            "certificate_error": REFUSED,
            "sample_gaps": [],
        },
        rows=({"kind": "static", "contract": CONTRACT, "param_names": NAMES, "covariance": COV},),
        fits=(("static", CONTRACT),),
        columns={
            "diagnosis_error": NOT_DIAGNOSED,
            "conformity_note": NO_LIMITS,
            "certificate_error": REFUSED,
        },
    ),
    # a fit stored before its row existed: it gets one of the kind its object states, for each kind
    "R-ORPHAN": Case(
        "completed", {**SETUP, "calibration": DYNAMIC, "sample_gaps": []}, fits=(("dynamic", DYNAMIC),)
    ),
    "R-ORPHAN-SCALAR": Case(
        "completed", {**SETUP, "calibration": SCALAR, "sample_gaps": []}, fits=(("scalar", SCALAR),)
    ),
    "R-ORPHAN-STATIC": Case(
        "completed", {**SETUP, "calibration": CONTRACT, "sample_gaps": []}, fits=(("static", CONTRACT),)
    ),
    # a moving fit stored twice, as the service wrote it
    "R-MOVING": Case(
        "completed",
        {**SETUP, "calibration": DYNAMIC, "sample_gaps": []},
        rows=({"kind": "dynamic", "contract": DYNAMIC, "param_names": NAMES, "covariance": COV},),
        fits=(("dynamic", DYNAMIC),),
    ),
    # the copy in params was changed (g_check.before added), the row was not: both kept
    "R-DIFF": Case(
        "completed",
        {
            **SETUP,
            "calibration": {**CONTRACT, "g_check": {**CONTRACT["g_check"], "before": BEFORE}},
            "sample_gaps": [],
        },
        rows=({"kind": "scalar", "contract": CONTRACT, "param_names": NAMES[:9], "covariance": COV[:9, :9]},),
        fits=(
            ("scalar", CONTRACT),
            ("scalar", {**CONTRACT, "g_check": {**CONTRACT["g_check"], "before": BEFORE}}),
        ),
    ),
    # recording: one gap so far, no sample count yet
    "R-LIVE": Case("running", {**SETUP, "sample_gaps": GAPS[:1]}, n_samples=None, gaps=tuple(GAPS[:1])),
    # values that do not fit their homes stay in params as they were
    "R-ODD": Case(
        "failed",
        {
            **SETUP,
            "calibration": "not a fit",
            "diagnosis": ["not", "an", "object"],
            "conformity_note": 3,
            "sample_gaps": [{"n_lost": 4, "window_index": 3, "cause": "dropped"}],
        },
        kept=("calibration", "diagnosis", "conformity_note", "sample_gaps"),
    ),
}
MOVED = ("calibration", "diagnosis", "diagnosis_error", "certificate_error", "conformity_note", "sample_gaps")


def _fill_at_0004(engine: Engine) -> None:
    at_revision(engine, "0004")
    with engine.begin() as conn:
        for run_id, case in CASES.items():
            conn.execute(
                sa.insert(RUN).values(
                    id=run_id,
                    unit_id=1,
                    bench_id=1,
                    procedure="static-12",
                    state=case.state,
                    outcome=None,
                    progress=1.0 if case.state == "completed" else 0.5,
                    params=copy.deepcopy({"run_id": run_id, **case.params}),
                    resume_count=0,
                    limit_checks=[],
                    n_samples=case.n_samples,
                    kind="calibration",
                )
            )
            for row in case.rows:
                conn.execute(sa.insert(FIT).values(run_id=run_id, **copy.deepcopy(row)))
            for i in range(3):
                conn.execute(
                    sa.insert(WINDOW).values(
                        run_id=run_id,
                        index=i,
                        label=f"pose {i}",
                        kind="static",
                        start_s=10.0 * i,
                        end_s=10.0 * i + 3.0,
                        n_samples=300,
                        pose_deg=[0.0, 90.0 * i],
                        means={"temp_c": 24.9},
                    )
                )
        conn.execute(sa.insert(FINDING).values(run_id="R-DONE", **FINDING_ROW))


def _counts(engine: Engine) -> dict[str, int]:
    return row_counts(engine, ("run", "run_window", "finding", "run_audit"))


def _check_upgrade(engine: Engine) -> None:
    from api.routes.views import run_out
    from db.models import FitModel, Run
    from db.repo.gaps import list_gaps
    from db.repo.results import results_of_runs

    with make_session_factory(engine).begin() as s:
        results = results_of_runs(s, list(CASES))
        for run_id, case in CASES.items():
            run = s.get(Run, run_id)
            assert run is not None
            original = {"run_id": run_id, **case.params}
            expected = {k: v for k, v in original.items() if k not in MOVED or k in case.kept}
            assert run.params == expected, run_id
            for name in ("diagnosis", "diagnosis_error", "certificate_error", "conformity_note"):
                assert getattr(run, name) == case.columns.get(name), (run_id, name)
            rows = s.scalars(sa.select(FitModel).where(FitModel.run_id == run_id).order_by(FitModel.id)).all()
            assert [(r.kind.value, r.contract) for r in rows] == list(case.fits), run_id
            assert [dataclasses.asdict(g) for g in list_gaps(s, run_id)] == list(case.gaps), run_id
            # what the REST object shows is what params held
            out = run_out(run, "SN-1", results=results[run_id], with_diagnosis=True)
            shown_fit = original.get("calibration")
            assert out.calibration == (shown_fit if isinstance(shown_fit, dict) else None), run_id
            assert out.diagnosis == case.columns.get("diagnosis"), run_id
            assert out.conformity_note == case.columns.get("conformity_note"), run_id
            assert out.certificate_note == case.columns.get("certificate_error"), run_id
            assert [g.model_dump() for g in out.gaps or []] == list(case.gaps), run_id
            assert out.n_samples_lost == (7 if case.gaps else (0 if case.n_samples is not None else None))
        covariances = {r.run_id: r.covariance for r in s.scalars(sa.select(FitModel).order_by(FitModel.id))}
        # the row added for a changed copy carries the covariance of the row it supersedes
        assert covariances["R-DIFF"] is not None and np.array_equal(covariances["R-DIFF"], COV[:9, :9])
        assert covariances["R-ORPHAN"] is None


def _check_upgrade_and_downgrade(engine: Engine) -> None:
    _fill_at_0004(engine)
    before = _counts(engine)
    upgrade(engine, "0005")
    assert current_revision(engine) == "0005"
    assert _counts(engine) == before
    _check_upgrade(engine)
    downgrade(engine, "0004")
    assert current_revision(engine) == "0004"
    assert _counts(engine) == before  # no child row went with the dropped columns
    assert "sample_gap" not in sa.inspect(engine).get_table_names()
    with engine.connect() as conn:
        stored = dict(conn.execute(sa.select(RUN.c.id, RUN.c.params)).all())
        n_fits: dict[str, int] = dict(
            conn.execute(sa.select(FIT.c.run_id, sa.func.count()).group_by(FIT.c.run_id)).all()
        )
    for run_id, case in CASES.items():
        assert stored[run_id] == {"run_id": run_id, **case.params}, run_id
        assert n_fits.get(run_id, 0) == len(case.fits), run_id  # the rows the upgrade added stay
    upgrade(engine)  # and up again: the same homes
    _check_upgrade(engine)


def test_0005_moves_every_result(empty_engine: Engine) -> None:
    """On SQLite and on PostgreSQL (``tests.pg.empty_engine``)."""
    _check_upgrade_and_downgrade(empty_engine)

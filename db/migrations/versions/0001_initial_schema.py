"""Initial schema: benches, units, runs, windows, sample chunks, fits, findings, certificates,
drift checks, API tokens.

Revision ID: 0001
Revises: (none)
Create Date: 2026-11-21 23:43:44.759932
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

import db.types

revision: str = "0001"
down_revision: str | None = None
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.create_table(
        "api_token",
        sa.Column("id", sa.Integer(), autoincrement=True, nullable=False),
        sa.Column(
            "role",
            sa.Enum(
                "viewer",
                "operator",
                "admin",
                name="token_role",
                native_enum=False,
                create_constraint=True,
                length=16,
            ),
            nullable=False,
        ),
        sa.Column("token_hash", sa.String(length=64), nullable=False),
        sa.Column("label", sa.String(length=200), nullable=False),
        sa.Column("revoked_at", db.types.UtcDateTime(), nullable=True),
        sa.Column("last_used_at", db.types.UtcDateTime(), nullable=True),
        sa.Column(
            "created_at", db.types.UtcDateTime(), server_default=sa.func.current_timestamp(), nullable=False
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_api_token")),
        sa.UniqueConstraint("token_hash", name=op.f("uq_api_token__token_hash")),
    )
    op.create_table(
        "bench",
        sa.Column("id", sa.Integer(), autoincrement=True, nullable=False),
        sa.Column("name", sa.String(length=100), nullable=False),
        sa.Column("table_url", sa.String(length=500), nullable=True),
        sa.Column("daq_url", sa.String(length=500), nullable=True),
        sa.Column(
            "created_at", db.types.UtcDateTime(), server_default=sa.func.current_timestamp(), nullable=False
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_bench")),
        sa.UniqueConstraint("name", name=op.f("uq_bench__name")),
    )
    op.create_table(
        "unit",
        sa.Column("id", sa.Integer(), autoincrement=True, nullable=False),
        sa.Column("serial", sa.String(length=100), nullable=False),
        sa.Column("model", sa.String(length=200), nullable=True),
        sa.Column("channel_unit", sa.String(length=16), nullable=True),
        sa.Column("bench_id", sa.Integer(), nullable=True),
        sa.Column(
            "created_at", db.types.UtcDateTime(), server_default=sa.func.current_timestamp(), nullable=False
        ),
        sa.ForeignKeyConstraint(
            ["bench_id"], ["bench.id"], name=op.f("fk_unit__bench_id__bench"), ondelete="SET NULL"
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_unit")),
        sa.UniqueConstraint("serial", name=op.f("uq_unit__serial")),
    )
    with op.batch_alter_table("unit", schema=None) as batch_op:
        batch_op.create_index(batch_op.f("ix_unit__bench_id"), ["bench_id"], unique=False)

    op.create_table(
        "run",
        sa.Column("id", sa.String(length=64), nullable=False),
        sa.Column("unit_id", sa.Integer(), nullable=False),
        sa.Column("bench_id", sa.Integer(), nullable=True),
        sa.Column("procedure", sa.String(length=100), nullable=False),
        sa.Column(
            "state",
            sa.Enum(
                "queued",
                "running",
                "paused",
                "completed",
                "failed",
                "error",
                "aborted",
                "interrupted",
                "suspended",
                name="run_state",
                native_enum=False,
                create_constraint=True,
                length=16,
            ),
            nullable=False,
        ),
        sa.Column("outcome", sa.String(length=16), nullable=True),
        sa.Column("progress", sa.Float(), nullable=False),
        sa.Column("recording_path", sa.String(length=1000), nullable=True),
        sa.Column("params", sa.JSON(), nullable=False),
        sa.Column("started_at", db.types.UtcDateTime(), nullable=True),
        sa.Column("finished_at", db.types.UtcDateTime(), nullable=True),
        sa.Column("heartbeat_at", db.types.UtcDateTime(), nullable=True),
        sa.Column("owner_pid", sa.Integer(), nullable=True),
        sa.Column("owner_host", sa.String(length=255), nullable=True),
        sa.Column("error", sa.Text(), nullable=True),
        sa.Column("last_complete_window", sa.Integer(), nullable=True),
        sa.Column("resume_count", sa.Integer(), nullable=False),
        sa.Column("n_samples", sa.BigInteger(), nullable=True),
        sa.Column("limit_checks", sa.JSON(), nullable=False),
        sa.Column(
            "created_at", db.types.UtcDateTime(), server_default=sa.func.current_timestamp(), nullable=False
        ),
        sa.CheckConstraint("progress >= 0 AND progress <= 1", name=op.f("ck_run__progress_range")),
        sa.ForeignKeyConstraint(
            ["bench_id"], ["bench.id"], name=op.f("fk_run__bench_id__bench"), ondelete="SET NULL"
        ),
        sa.ForeignKeyConstraint(
            ["unit_id"], ["unit.id"], name=op.f("fk_run__unit_id__unit"), ondelete="RESTRICT"
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_run")),
    )
    with op.batch_alter_table("run", schema=None) as batch_op:
        batch_op.create_index(batch_op.f("ix_run__bench_id"), ["bench_id"], unique=False)
        batch_op.create_index(batch_op.f("ix_run__state"), ["state"], unique=False)
        batch_op.create_index(batch_op.f("ix_run__unit_id"), ["unit_id"], unique=False)

    op.create_table(
        "certificate",
        sa.Column("id", sa.Integer(), autoincrement=True, nullable=False),
        sa.Column("run_id", sa.String(length=64), nullable=False),
        sa.Column("unit_id", sa.Integer(), nullable=False),
        sa.Column("year", sa.Integer(), nullable=False),
        sa.Column("serial", sa.Integer(), nullable=False),
        sa.Column("number", sa.String(length=32), nullable=False),
        sa.Column("content", sa.JSON(), nullable=False),
        sa.Column("sha256", sa.String(length=64), nullable=False),
        sa.Column("pdf", sa.LargeBinary(), nullable=True),
        sa.Column("issued_at", db.types.UtcDateTime(), nullable=False),
        sa.Column(
            "created_at", db.types.UtcDateTime(), server_default=sa.func.current_timestamp(), nullable=False
        ),
        sa.ForeignKeyConstraint(
            ["run_id"], ["run.id"], name=op.f("fk_certificate__run_id__run"), ondelete="RESTRICT"
        ),
        sa.ForeignKeyConstraint(
            ["unit_id"], ["unit.id"], name=op.f("fk_certificate__unit_id__unit"), ondelete="RESTRICT"
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_certificate")),
        sa.UniqueConstraint("number", name=op.f("uq_certificate__number")),
        sa.UniqueConstraint("year", "serial", name=op.f("uq_certificate__year_serial")),
    )
    with op.batch_alter_table("certificate", schema=None) as batch_op:
        batch_op.create_index(batch_op.f("ix_certificate__run_id"), ["run_id"], unique=False)
        batch_op.create_index(batch_op.f("ix_certificate__unit_id"), ["unit_id"], unique=False)

    op.create_table(
        "finding",
        sa.Column("id", sa.Integer(), autoincrement=True, nullable=False),
        sa.Column("run_id", sa.String(length=64), nullable=False),
        sa.Column("effect", sa.String(length=64), nullable=False),
        sa.Column("summary", sa.Text(), nullable=False),
        sa.Column("parameters", sa.JSON(), nullable=False),
        sa.Column("sigma", sa.JSON(), nullable=False),
        sa.Column("delta_bic", sa.Double(), nullable=True),
        sa.Column("residual_rms_after", sa.Double(), nullable=True),
        sa.Column(
            "created_at", db.types.UtcDateTime(), server_default=sa.func.current_timestamp(), nullable=False
        ),
        sa.ForeignKeyConstraint(
            ["run_id"], ["run.id"], name=op.f("fk_finding__run_id__run"), ondelete="CASCADE"
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_finding")),
    )
    with op.batch_alter_table("finding", schema=None) as batch_op:
        batch_op.create_index(batch_op.f("ix_finding__run_id"), ["run_id"], unique=False)

    op.create_table(
        "fit_model",
        sa.Column("id", sa.Integer(), autoincrement=True, nullable=False),
        sa.Column("run_id", sa.String(length=64), nullable=False),
        sa.Column(
            "kind",
            sa.Enum(
                "static",
                "scalar",
                "dynamic",
                name="fit_kind",
                native_enum=False,
                create_constraint=True,
                length=16,
            ),
            nullable=False,
        ),
        sa.Column("contract", sa.JSON(), nullable=False),
        sa.Column("param_names", sa.JSON(), nullable=False),
        sa.Column("covariance", db.types.NpyArray(), nullable=True),
        sa.Column(
            "created_at", db.types.UtcDateTime(), server_default=sa.func.current_timestamp(), nullable=False
        ),
        sa.ForeignKeyConstraint(
            ["run_id"], ["run.id"], name=op.f("fk_fit_model__run_id__run"), ondelete="CASCADE"
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_fit_model")),
    )
    with op.batch_alter_table("fit_model", schema=None) as batch_op:
        batch_op.create_index(batch_op.f("ix_fit_model__run_id"), ["run_id"], unique=False)

    op.create_table(
        "run_window",
        sa.Column("id", sa.Integer(), autoincrement=True, nullable=False),
        sa.Column("run_id", sa.String(length=64), nullable=False),
        sa.Column("index", sa.Integer(), nullable=False),
        sa.Column("label", sa.String(length=100), nullable=False),
        sa.Column("kind", sa.String(length=16), nullable=False),
        sa.Column("start_s", sa.Double(), nullable=False),
        sa.Column("end_s", sa.Double(), nullable=False),
        sa.Column("n_samples", sa.Integer(), nullable=False),
        sa.Column("pose_deg", sa.JSON(), nullable=False),
        sa.Column("means", sa.JSON(), nullable=False),
        sa.Column("step_index", sa.Integer(), nullable=True),
        sa.Column(
            "created_at", db.types.UtcDateTime(), server_default=sa.func.current_timestamp(), nullable=False
        ),
        sa.ForeignKeyConstraint(
            ["run_id"], ["run.id"], name=op.f("fk_run_window__run_id__run"), ondelete="CASCADE"
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_run_window")),
        sa.UniqueConstraint("run_id", "index", name=op.f("uq_run_window__run_id_index")),
    )
    op.create_table(
        "sample_chunk",
        sa.Column("id", sa.Integer(), autoincrement=True, nullable=False),
        sa.Column("run_id", sa.String(length=64), nullable=False),
        sa.Column("seq", sa.Integer(), nullable=False),
        sa.Column("first_sample", sa.BigInteger(), nullable=False),
        sa.Column("n_samples", sa.Integer(), nullable=False),
        sa.Column("last_t_s", sa.Double(), nullable=False),
        sa.Column("end_byte", sa.BigInteger(), nullable=True),
        sa.Column("daq_seq", sa.BigInteger(), nullable=True),
        sa.Column("window_index", sa.Integer(), nullable=True),
        sa.Column(
            "created_at", db.types.UtcDateTime(), server_default=sa.func.current_timestamp(), nullable=False
        ),
        sa.ForeignKeyConstraint(
            ["run_id"], ["run.id"], name=op.f("fk_sample_chunk__run_id__run"), ondelete="CASCADE"
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_sample_chunk")),
        sa.UniqueConstraint("run_id", "seq", name=op.f("uq_sample_chunk__run_id_seq")),
    )
    op.create_table(
        "drift_check",
        sa.Column("id", sa.Integer(), autoincrement=True, nullable=False),
        sa.Column("unit_id", sa.Integer(), nullable=False),
        sa.Column("run_id", sa.String(length=64), nullable=True),
        sa.Column("reference_certificate_id", sa.Integer(), nullable=True),
        sa.Column("result", sa.JSON(), nullable=False),
        sa.Column("flagged", sa.Boolean(create_constraint=True, name="flagged_bool"), nullable=False),
        sa.Column("checked_at", db.types.UtcDateTime(), nullable=False),
        sa.Column(
            "created_at", db.types.UtcDateTime(), server_default=sa.func.current_timestamp(), nullable=False
        ),
        sa.ForeignKeyConstraint(
            ["reference_certificate_id"],
            ["certificate.id"],
            name=op.f("fk_drift_check__reference_certificate_id__certificate"),
            ondelete="SET NULL",
        ),
        sa.ForeignKeyConstraint(
            ["run_id"], ["run.id"], name=op.f("fk_drift_check__run_id__run"), ondelete="SET NULL"
        ),
        sa.ForeignKeyConstraint(
            ["unit_id"], ["unit.id"], name=op.f("fk_drift_check__unit_id__unit"), ondelete="CASCADE"
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_drift_check")),
    )
    with op.batch_alter_table("drift_check", schema=None) as batch_op:
        batch_op.create_index(
            batch_op.f("ix_drift_check__reference_certificate_id"), ["reference_certificate_id"], unique=False
        )
        batch_op.create_index(batch_op.f("ix_drift_check__run_id"), ["run_id"], unique=False)
        batch_op.create_index(batch_op.f("ix_drift_check__unit_id"), ["unit_id"], unique=False)


def downgrade() -> None:
    with op.batch_alter_table("drift_check", schema=None) as batch_op:
        batch_op.drop_index(batch_op.f("ix_drift_check__unit_id"))
        batch_op.drop_index(batch_op.f("ix_drift_check__run_id"))
        batch_op.drop_index(batch_op.f("ix_drift_check__reference_certificate_id"))

    op.drop_table("drift_check")
    op.drop_table("sample_chunk")
    op.drop_table("run_window")
    with op.batch_alter_table("fit_model", schema=None) as batch_op:
        batch_op.drop_index(batch_op.f("ix_fit_model__run_id"))

    op.drop_table("fit_model")
    with op.batch_alter_table("finding", schema=None) as batch_op:
        batch_op.drop_index(batch_op.f("ix_finding__run_id"))

    op.drop_table("finding")
    with op.batch_alter_table("certificate", schema=None) as batch_op:
        batch_op.drop_index(batch_op.f("ix_certificate__unit_id"))
        batch_op.drop_index(batch_op.f("ix_certificate__run_id"))

    op.drop_table("certificate")
    with op.batch_alter_table("run", schema=None) as batch_op:
        batch_op.drop_index(batch_op.f("ix_run__unit_id"))
        batch_op.drop_index(batch_op.f("ix_run__state"))
        batch_op.drop_index(batch_op.f("ix_run__bench_id"))

    op.drop_table("run")
    with op.batch_alter_table("unit", schema=None) as batch_op:
        batch_op.drop_index(batch_op.f("ix_unit__bench_id"))

    op.drop_table("unit")
    op.drop_table("bench")
    op.drop_table("api_token")

"""The lab's benches and their state (viewer)."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter

from api.auth import Role
from api.deps import SessionDep, ViewerDep
from api.schemas import BenchOut
from db.repo.benches import bench_status

router = APIRouter(prefix="/api/benches", tags=["benches"])


@router.get("", response_model=list[BenchOut])
def benches(session: SessionDep, role: ViewerDep) -> list[BenchOut]:
    """Every bench in the database, by name: ``idle``, ``busy`` (with the run holding it) or
    ``offline`` (its agent has not reported for 30 s, or, an agent of this host, its process is
    gone), the procedures its table can run and its
    bench file, as its agent reports them, and how many runs wait for it. A run names one in
    ``POST /api/runs`` (``bench``). The bench file's path on the agent's host is shown to
    operators and admins only (a viewer or anonymous reader sees its name, version and sha256)."""
    with session.begin():
        return [
            BenchOut(
                name=b.name,
                state=b.state,
                agent_seen_at=b.agent_seen_at,
                agent_host=b.agent_host,
                procedures=list(b.procedures),
                bench_file=b.bench_file if role >= Role.OPERATOR else _without_path(b.bench_file),
                running_run=b.holding_run,
                n_queued=b.n_queued,
            )
            for b in bench_status(session)
        ]


def _without_path(bench_file: dict[str, Any] | None) -> dict[str, Any] | None:
    return None if bench_file is None else {k: v for k, v in bench_file.items() if k != "path"}

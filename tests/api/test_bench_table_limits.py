"""A table slower than the default, stated in its bench file (``[table.limits]``), is what every
check of a procedure uses: a start over REST and by ``calbench run``, the preview, a resume and
the planner (``GET /api/plan``, ``calbench plan``) — the rate 200 deg/s of rate-1axis the default
table (300 deg/s) accepts is refused naming the file's 120 deg/s, and the plan is timed on the
file's accelerations and settles as long as the file says."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from api.cli import main
from api.main import create_app
from bench.bench_config import SIM_BENCH_FILE, load_bench_config
from bench.procedures import DEFAULT_TABLE_LIMITS, build_procedure, preview
from tests.api.test_resume_refused import store_interrupted
from tests.support.service_helpers import OP, VIEW, service_settings

pytestmark = pytest.mark.timeout(180)

SLOW = """
[table.limits]
max_rate_deg_s = [120.0, 120.0, 120.0]
max_acc_deg_s2 = [15.0, 15.0, 15.0]
continuous = [true, false, true]
settle_s = {settle}
"""
PLAN = {"white_ug_rt_hz": 250, "wander_ug": 40, "wander_tau_s": 200, "scale_ppm": 80, "max_minutes": 30}


def slow_bench(tmp: Path, settle_s: float = 2.0) -> Path:
    text = SIM_BENCH_FILE.read_text(encoding="utf-8").replace(
        "[gravity]", SLOW.format(settle=settle_s) + "[gravity]"
    )
    path = tmp / f"slow-{settle_s:g}.toml"
    path.write_text(text.replace('name = "simulated bench"', 'name = "slow table"'), encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def slow(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    tmp = tmp_path_factory.mktemp("slow-table")
    settings = service_settings(tmp, bench_file=slow_bench(tmp), agent="external")
    with TestClient(create_app(settings, start_scheduler=False)) as c:
        c.tmp = tmp  # type: ignore[attr-defined]
        yield c


@pytest.fixture(scope="module")
def default(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    tmp = tmp_path_factory.mktemp("default-table")
    with TestClient(create_app(service_settings(tmp, agent="external"), start_scheduler=False)) as c:
        yield c


def test_rest_start_refuses_a_rate_beyond_the_file_s_table(slow: TestClient, default: TestClient) -> None:
    body = {"unit_serial": "SN-LIM-1", "procedure": "rate-1axis", "dwell_s": 3.0}
    r = slow.post("/api/runs", json=body, headers=OP)
    assert r.status_code == 422, r.text
    assert "rate 200 deg/s exceeds the axis 1 limit 120 deg/s" in r.json()["detail"]
    assert default.post("/api/runs", json=body, headers=OP).status_code == 202  # 300 deg/s: queued


def test_the_preview_is_timed_on_the_file_s_table(slow: TestClient, default: TestClient) -> None:
    limits = load_bench_config(slow_bench(slow.tmp)).table_limits()  # type: ignore[attr-defined]
    proc = build_procedure("static-12", dwell_s=3.0)
    seen = {}
    for name, client in (("slow", slow), ("default", default)):
        r = client.get("/api/procedures/static-12/preview", params={"dwell_s": 3.0}, headers=VIEW)
        assert r.status_code == 200, r.text
        seen[name] = r.json()["duration_s"]
    assert seen["slow"] == pytest.approx(preview(proc, limits).duration_s, rel=1e-12)
    assert seen["default"] == pytest.approx(preview(proc, DEFAULT_TABLE_LIMITS).duration_s, rel=1e-12)
    assert seen["slow"] > seen["default"]


def test_rest_resume_refuses_rates_the_file_s_table_cannot_turn(slow: TestClient) -> None:
    sessions = slow.app.state.services.sessions  # type: ignore[attr-defined]
    store_interrupted(
        sessions, "run-slow-table", "rate-1axis", {"dwell_s": 5.0, "rates_deg_s": [150.0, 100.0]}, 3
    )
    r = slow.post("/api/runs/run-slow-table/resume", headers=OP)
    assert r.status_code == 409, r.text
    assert "rate 150 deg/s exceeds the axis 1 limit 120 deg/s" in r.json()["detail"]


def test_calbench_run_refuses_a_rate_beyond_the_file_s_table(
    slow: TestClient, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    tmp: Path = slow.tmp  # type: ignore[attr-defined]
    monkeypatch.setenv("CALBENCH_DATABASE_URL", f"sqlite:///{tmp / 'cli.db'}")
    monkeypatch.setenv("CALBENCH_DATA_DIR", str(tmp / "cli"))
    code = main(["run", "rate-1axis", "--unit", "SN-LIM-2", "--sim", "--bench-file", str(slow_bench(tmp))])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1, err
    assert "rate 200 deg/s exceeds the axis 1 limit 120 deg/s" in err


def test_the_plan_is_timed_on_the_file_s_table(
    slow: TestClient, default: TestClient, capsys: pytest.CaptureFixture[str]
) -> None:
    tmp: Path = slow.tmp  # type: ignore[attr-defined]
    limits = load_bench_config(slow_bench(tmp)).table_limits()
    r = slow.get("/api/plan", params=PLAN, headers=VIEW)
    assert r.status_code == 200, r.text
    plan = r.json()["plan"]
    start = r.json()["start"]
    proc = build_procedure(start["procedure"], dwell_s=start["dwell_s"], **start["parameters"])
    # the planned design's table time is its preview on the file's limits, not on the default's
    assert plan["duration_s"] == pytest.approx(preview(proc, limits).duration_s, rel=1e-12)
    assert preview(proc, DEFAULT_TABLE_LIMITS).duration_s < plan["duration_s"]
    # calbench plan on the same bench file plans the same design
    argv = ["plan", "--white", "250", "--wander", "40", "--wander-tau", "200", "--scale", "80"]
    code = main(
        [*argv, "--max-minutes", "30", "--fit", "window", "--json", "--bench-file", str(slow_bench(tmp))]
    )
    cli = json.loads(capsys.readouterr().out)
    assert code == 0 and cli["plan"]["duration_s"] == pytest.approx(plan["duration_s"], rel=1e-12)
    assert cli["plan"]["parameters"] == plan["parameters"]


def test_the_plan_settles_as_long_as_the_file_says(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = str(slow_bench(tmp_path, settle_s=3.5))
    argv = ["plan", "--white", "250", "--scale", "200", "--max-minutes", "30", "--fit", "window", "--json"]
    assert main([*argv, "--bench-file", path]) == 0
    assert json.loads(capsys.readouterr().out)["plan"]["parameters"]["settle_s"] == 3.5
    assert main([*argv, "--bench-file", path, "--settle-s", "1"]) == 1
    out = json.loads(capsys.readouterr().out)
    assert out["plan"] is None
    assert any("settling 1 s is shorter than the table's 3.5 s" in p for p in out["problems"]), out


def test_the_agent_offers_only_what_the_file_s_table_can_run(slow: TestClient) -> None:
    from station.agent.bench_agent import runnable_procedures

    settings = service_settings(slow.tmp)  # type: ignore[attr-defined]
    on_slow = runnable_procedures(settings, load_bench_config(slow_bench(slow.tmp)))  # type: ignore[attr-defined]
    on_default = runnable_procedures(settings, load_bench_config(SIM_BENCH_FILE))
    assert "rate-1axis" in on_default and "rate-1axis" not in on_slow  # 200 deg/s > 120 deg/s
    assert "static-12" in on_slow


def test_a_bench_file_broken_after_the_start_answers_viewers_503_without_its_path(tmp_path: Path) -> None:
    path = slow_bench(tmp_path)
    with TestClient(
        create_app(service_settings(tmp_path, bench_file=path, agent="external"), start_scheduler=False)
    ) as client:
        path.write_text(path.read_text().replace("max_rate_deg_s = [120.0,", "max_rate_deg_s = [nan,"))
        for r in (
            client.get("/api/procedures/static-12/preview", headers=VIEW),
            client.get("/api/plan", params=PLAN, headers=VIEW),
        ):
            assert r.status_code == 503, r.text
            detail = r.json()["detail"]
            assert "table.limits.max_rate_deg_s[0]" in detail and str(tmp_path) not in detail

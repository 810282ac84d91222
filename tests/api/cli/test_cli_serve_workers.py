"""``calbench serve --workers N``: its refusals, and the workers' app built from the parent's settings."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from api.cli import main
from api.cli.serve import SERVE_CONFIG_ENV, worker_app
from tests.support.service_helpers import VIEW, service_settings


@pytest.mark.parametrize(
    ("args", "says"),
    [
        (["--workers", "0"], "--workers 0: expected 1..64"),
        (["--workers", "65"], "--workers 65: expected 1..64"),
        (["--workers", "2", "--agent", "embedded"], "--workers 2 with --agent embedded"),
    ],
)
def test_serve_refuses_bad_worker_counts_on_one_line(
    args: list[str],
    says: str,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    monkeypatch.setenv("CALBENCH_DATA_DIR", str(tmp_path))
    monkeypatch.setenv("CALBENCH_TOKENS", "viewer:viewer-secret-0001")
    assert main(["serve", "--sim", *args]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and says in err, err


def test_a_worker_builds_the_app_from_the_settings_and_tokens_it_is_handed(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    settings = service_settings(tmp_path, bench_name="bench-worker", agent="external", tokens=[])
    config = {"settings": settings.model_dump(mode="json"), "extra_tokens": {"handed-admin-0001": "admin"}}
    monkeypatch.setenv(SERVE_CONFIG_ENV, json.dumps(config))
    monkeypatch.setenv("CALBENCH_BENCH_NAME", "not-this-one")  # the handed settings win over the environment
    with TestClient(worker_app()) as client:
        health = client.get("/api/health").json()
        assert health["bench"] == "bench-worker" and health["database"] == "sqlite"
        assert health["live_updates"] == "poll"
        assert client.get("/api/health").headers["x-calbench-worker"] == health["worker"]
        assert client.get("/api/whoami", headers={"Authorization": "Bearer handed-admin-0001"}).json() == {
            "role": "admin"
        }
        assert client.get("/api/whoami", headers=VIEW).status_code == 401  # no other token


@pytest.mark.parametrize("raw", [None, "", "{", '{"settings": {}}', '{"settings": 3, "extra_tokens": {}}'])
def test_a_worker_without_its_configuration_says_so(raw: str | None, monkeypatch: pytest.MonkeyPatch) -> None:
    if raw is None:
        monkeypatch.delenv(SERVE_CONFIG_ENV, raising=False)
    else:
        monkeypatch.setenv(SERVE_CONFIG_ENV, raw)
    with pytest.raises(RuntimeError, match=f"{SERVE_CONFIG_ENV}: missing or malformed"):
        worker_app()

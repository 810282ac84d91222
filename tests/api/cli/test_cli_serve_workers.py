"""``calbench serve --workers N``: its refusals, and the workers' app built from the parent's settings."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from api.cli import main
from api.cli.serve import SERVE_CONFIG_ENV, serve_settings, worker_app
from tests.support.service_helpers import OP, OPERATOR, VIEW, VIEWER, service_settings, signed_link


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


def _serve_args(**over: object) -> argparse.Namespace:
    values: dict[str, object] = {
        "sim": True, "sim_speed": None, "port": 8000, "workers": 2, "agent": "external", "bench_file": None
    }  # fmt: skip
    values.update(over)
    return argparse.Namespace(**values)


def test_a_link_signed_by_one_worker_opens_on_the_other(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Two workers of one ``calbench serve`` (two apps built from what it hands them, one database):
    every link either signs opens on both, whichever signed it."""
    monkeypatch.setenv("CALBENCH_DATA_DIR", str(tmp_path))
    monkeypatch.setenv("CALBENCH_TOKENS", f"operator:{OPERATOR},viewer:{VIEWER}")
    monkeypatch.setenv("CALBENCH_DRIFT_TIME", "")
    monkeypatch.delenv("CALBENCH_LINK_KEY", raising=False)
    settings, generated = serve_settings(_serve_args())
    assert len(settings.link_key) >= 32
    monkeypatch.setenv(
        SERVE_CONFIG_ENV,
        json.dumps({"settings": settings.model_dump(mode="json"), "extra_tokens": generated}),
    )
    with TestClient(worker_app()) as a, TestClient(worker_app()) as b:
        assert (
            a.get("/api/health").headers["x-calbench-worker"]
            != b.get("/api/health").headers["x-calbench-worker"]
        )
        run_id = a.post(
            "/api/runs", json={"unit_serial": "SN-LINK", "procedure": "static-12"}, headers=OP
        ).json()["id"]
        opened = []
        for signer, opener in ((a, b), (b, a), (a, a), (b, b)):
            url = signed_link(signer, f"/api/runs/{run_id}/events")
            with opener.stream("GET", url) as s:
                opened.append(s.status_code)
                if s.status_code == 200:
                    assert next(line for line in s.iter_lines() if line.startswith("event:"))
        assert opened == [200, 200, 200, 200]
        forged = signed_link(a, f"/api/runs/{run_id}/events")[:-3] + "AAA"
        assert b.get(forged).status_code == 401


def test_a_configured_link_key_is_kept_and_a_short_one_refused(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setenv("CALBENCH_DATA_DIR", str(tmp_path))
    monkeypatch.setenv("CALBENCH_TOKENS", f"viewer:{VIEWER}")
    monkeypatch.setenv("CALBENCH_LINK_KEY", "k" * 40)
    assert serve_settings(_serve_args())[0].link_key == "k" * 40
    monkeypatch.setenv("CALBENCH_LINK_KEY", "short")
    assert main(["serve", "--sim", "--workers", "2", "--agent", "external"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "CALBENCH_LINK_KEY has 5 characters; expected at least 32" in err, err

"""A service without ``CALBENCH_TOKENS`` keeps its admin token across a restart: the first
start prints it once (stored hashed), the restarted process accepts the same secret and does
not print it again. Before, each start made a new admin token and the old one stopped working.
Against real ``calbench serve --sim`` processes."""

from __future__ import annotations

import hashlib
import re
import signal
import sqlite3
from pathlib import Path

import httpx
import pytest

from tests.e2e.service_process import ServiceProcess

pytestmark = [pytest.mark.slow, pytest.mark.timeout(300)]

FIRST = re.compile(r"admin token \(api_token (\d+), stored hashed, shown only now: keep it\): (\S+)")


def test_the_admin_token_survives_a_restart_and_is_printed_once(tmp_path: Path) -> None:
    svc = ServiceProcess(tmp_path, sim_speed=5.0)
    del svc.env["CALBENCH_TOKENS"]
    try:
        svc.start()
        match = FIRST.search(svc.log())
        assert match is not None, svc.log()
        token_id, secret = int(match[1]), match[2]
        admin = {"Authorization": f"Bearer {secret}"}
        made = httpx.post(
            f"{svc.base}/api/tokens", json={"role": "operator", "operator": "A. Tester"}, headers=admin
        )
        assert made.status_code == 201, made.text
        operator_secret = made.json()["secret"]
        svc.stop(signal.SIGTERM)  # the process ends (uvicorn re-raises the signal)
        # only the secret's SHA-256 is in the database
        with sqlite3.connect(svc.db) as conn:
            ((stored,),) = conn.execute("SELECT token_hash FROM api_token WHERE id = ?", (token_id,))
        assert stored == hashlib.sha256(secret.encode()).hexdigest()
        assert secret.encode() not in svc.db.read_bytes()

        svc.start()  # a new process on the same database
        assert secret not in svc.log() and FIRST.search(svc.log()) is None, svc.log()
        assert f"admin token printed at the first start holds (api_token {token_id})" in svc.log()
        tokens = httpx.get(f"{svc.base}/api/tokens", headers=admin)
        assert tokens.status_code == 200, tokens.text
        assert {t["operator"] for t in tokens.json()} >= {"A. Tester"}
        who = httpx.get(f"{svc.base}/api/whoami", headers={"Authorization": f"Bearer {operator_secret}"})
        assert who.status_code == 200 and who.json()["role"] == "operator"
        assert (
            httpx.get(f"{svc.base}/api/tokens", headers={"Authorization": "Bearer nope"}).status_code == 401
        )
    finally:
        svc.kill()

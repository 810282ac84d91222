"""Property-based API test: every operation of the OpenAPI schema, generated inputs, no 500s.

Runs on a simulated bench whose runs are never started for real: POST /api/runs is tried
with generated bodies (valid ones are queued and aborted at once by the next case), and
the operator token is sent so the write paths are exercised beyond 401.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest
import schemathesis
from fastapi.testclient import TestClient
from hypothesis import HealthCheck, given, settings

from api.main import create_app
from tests.support.service_helpers import OP, service_settings

pytestmark = [pytest.mark.slow, pytest.mark.timeout(600)]  # the whole API fuzzed from its OpenAPI schema
REQUEST_TIMEOUT_S = 120.0


@pytest.fixture(scope="module")
def app_client(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    tmp: Path = tmp_path_factory.mktemp("schemathesis")
    app = create_app(service_settings(tmp, run_dwell_s=1.0), start_scheduler=False)
    with TestClient(app) as client:
        yield client


def test_no_server_errors(app_client: TestClient) -> None:
    schema = schemathesis.openapi.from_asgi("/openapi.json", app_client.app)
    runner = app_client.app.state.services.runner  # type: ignore[attr-defined]
    checked = []
    for result in schema.get_all_operations():
        operation = result.ok()

        @given(case=operation.as_strategy())
        @settings(max_examples=12, deadline=None, suppress_health_check=list(HealthCheck), database=None)
        def no_500(case: schemathesis.Case) -> None:
            if runner.current is not None:  # keep the bench free for the next case
                runner.abort(runner.current.id)
                runner.wait_idle(60.0)
            # speed is for benchmarks: a request is waited for as long as the test's own budget
            # allows (an every-sample plan takes 5-20 s, docs/benchmarks.md), not schemathesis's 10 s
            response = case.call(headers=OP, timeout=REQUEST_TIMEOUT_S)
            assert response.status_code < 500, (case.method, case.formatted_path, response.text[:500])

        no_500()
        checked.append(f"{operation.method.upper()} {operation.path}")
    assert "POST /api/runs" in checked and "POST /api/recordings" in checked and len(checked) >= 14

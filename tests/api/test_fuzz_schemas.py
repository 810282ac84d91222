"""Property-based fuzzing of the API schemas and of the service with generated request bodies.

A request model either accepts a body, and then every text it keeps passes the text rules and
every number is finite, or refuses it with a validation error that strict JSON can carry (no
``NaN``); through the service every generated body answers below 500. Fast here
(``CALBENCH_FUZZ_EXAMPLES``, default 40); ``make fuzz`` runs thousands.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from pydantic import BaseModel, ValidationError

from api.error_handlers import json_safe
from api.main import create_app
from api.schemas import DriftRequest, LinkRequest, RunCreate, TokenCreate, UnitRegistration
from bench.inputs import check_text
from tests.support.service_helpers import OP, service_settings

EXAMPLES = int(os.environ.get("CALBENCH_FUZZ_EXAMPLES", "40"))
FUZZ = settings(
    max_examples=EXAMPLES,
    deadline=None,
    database=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
WEIRD_TEXT = st.one_of(
    st.text(max_size=30),
    st.sampled_from(
        ["", "SN-1", "static-12", "a\x00b", "\u202eSN", "ADXL\u2066", "1 Main St\nTown", "x" * 600]
    ),
)
VALUES = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-(10**30), 10**30),
    st.floats(),  # NaN and ±inf included
    WEIRD_TEXT,
    st.lists(st.integers(), max_size=3),
)
MODELS: dict[type[BaseModel], list[str]] = {
    RunCreate: ["unit_serial", "procedure", "dwell_s", "bench"],
    UnitRegistration: list(UnitRegistration.model_fields),
    TokenCreate: ["role", "label"],
    LinkRequest: ["path"],
    DriftRequest: ["unit_serial"],
}


@st.composite
def bodies(draw: st.DrawFn) -> tuple[type[BaseModel], dict[str, Any]]:
    model = draw(st.sampled_from(list(MODELS)))
    keys = draw(st.lists(st.sampled_from([*MODELS[model], "extra"]), unique=True, max_size=6))
    return model, {k: draw(VALUES) for k in keys}


@FUZZ
@given(bodies())
def test_models_accept_clean_values_or_refuse_in_strict_json(
    case: tuple[type[BaseModel], dict[str, Any]],
) -> None:
    model, body = case
    try:
        obj = model.model_validate(body)
    except ValidationError as exc:
        json.dumps(json_safe(list(exc.errors())), allow_nan=False)
        return
    for name, value in obj.model_dump().items():
        if isinstance(value, str):
            check_text(value, max_chars=600, multiline=name == "customer_address")
        if isinstance(value, float):
            assert math.isfinite(value), name


@pytest.fixture(scope="module")
def client(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    tmp: Path = tmp_path_factory.mktemp("fuzz-schemas")
    with TestClient(create_app(service_settings(tmp), start_scheduler=False)) as c:
        yield c


NUMBER_LITERALS = st.sampled_from(
    ["NaN", "Infinity", "-Infinity", "1e999", "9" * 40, "1e-300", "-0", "0.0177"]
)


@FUZZ
@given(
    field=st.sampled_from(["nominal_scale", "nominal_bias", "customer_name", "customer_address", "model"]),
    literal=st.one_of(NUMBER_LITERALS, WEIRD_TEXT.map(json.dumps)),
)
def test_unit_registration_never_500(client: TestClient, field: str, literal: str) -> None:
    body = "{" + json.dumps(field) + ": " + literal + "}"
    r = client.put("/api/units/SN-FUZZ", content=body, headers={**OP, "content-type": "application/json"})
    assert r.status_code in (200, 422), (body[:80], r.status_code, r.text[:300])


@FUZZ
@given(dwell=NUMBER_LITERALS, serial=WEIRD_TEXT.map(json.dumps))
def test_run_start_refusals_never_500(client: TestClient, dwell: str, serial: str) -> None:
    body = '{"unit_serial": ' + serial + ', "procedure": "no-such-procedure", "dwell_s": ' + dwell + "}"
    r = client.post("/api/runs", content=body, headers={**OP, "content-type": "application/json"})
    assert r.status_code == 422, (body[:80], r.status_code, r.text[:300])

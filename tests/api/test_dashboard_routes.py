"""The dashboard page and the plot series routes, checked against independent computations.

Runs are registered directly in the database and point at the shipped example
recording (``examples/static12_nonlinearity``), so no bench has to run: the series
the routes compute from the recording are compared with the fit's own contract, with
K⁻¹ applied through an explicit inverse, with a reference model whose answer is known
exactly (a scale 1 % high shrinks every |f̂| by 1.01), and with white noise whose Allan
deviation is σ/√m.
"""

from __future__ import annotations

import copy
import datetime as dt
import json
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient

from api.main import create_app
from api.plots.history_series import COVERAGE_K, HistoryPoint, coefficient_history
from api.plots.run_bundle import BundleCache, build_bundle
from api.plots.run_series import MIN_ALLAN_SAMPLES, allan_series, pick_noise_span
from bench.calibration import calibrate_recording
from bench.recording import Recording, Sidecar, read_recording
from db.models import RunState
from db.repo.results import add_fit
from db.repo.runs import create_run, finish_run
from db.repo.units import get_or_create_unit
from tests.conftest import EXAMPLES, STATIC_EXAMPLE
from tests.support.fits import stored_fit
from tests.support.service_helpers import OP, VIEW, service_settings

SERIAL = "SN-DASH-1"


@pytest.fixture(scope="module")
def example() -> Path:
    return EXAMPLES / f"{STATIC_EXAMPLE}.csv"


@pytest.fixture(scope="module")
def contract(example: Path) -> dict[str, Any]:
    return calibrate_recording(read_recording(example)).to_contract()


def _register(
    client: TestClient,
    run_id: str,
    state: RunState,
    path: str | None,
    cal: dict[str, Any] | None,
    created_s: float,
) -> None:
    sessions = client.app.state.services.sessions  # type: ignore[attr-defined]
    now = dt.datetime(2026, 1, 1, tzinfo=dt.UTC) + dt.timedelta(seconds=created_s)
    with sessions.begin() as s:
        unit = get_or_create_unit(s, SERIAL, channel_unit="V")
        create_run(
            s,
            run_id,
            unit.id,
            "static-12",
            recording_path=path,
            state=RunState.RUNNING,
            now=now,
        )
        if cal:
            add_fit(s, run_id, "static", cal)
        if state is not RunState.RUNNING:
            finish_run(s, run_id, state, outcome="PASS", now=now + dt.timedelta(seconds=60))


@pytest.fixture(scope="module")
def client(
    tmp_path_factory: pytest.TempPathFactory, example: Path, contract: dict[str, Any]
) -> Iterator[TestClient]:
    app = create_app(service_settings(tmp_path_factory.mktemp("dash")), start_scheduler=False)
    with TestClient(app) as c:
        off = copy.deepcopy(contract)
        off["scale_matrix"] = (1.01 * np.array(contract["scale_matrix"])).tolist()
        off["bias_sigma"] = [2 * s for s in contract["bias_sigma"]]
        _register(c, "run-old", RunState.COMPLETED, str(example), off, 0.0)
        _register(c, "run-new", RunState.COMPLETED, str(example), contract, 100.0)
        _register(c, "run-live", RunState.RUNNING, str(example), None, 200.0)
        _register(c, "run-gone", RunState.COMPLETED, str(example.with_name("missing.csv")), contract, 300.0)
        yield c


def test_the_page_and_its_assets_are_served(client: TestClient) -> None:
    page = client.get("/")
    assert page.status_code == 200 and page.headers["content-type"].startswith("text/html")
    assert 'src="/static/app.js"' in page.text and 'id="token-input"' in page.text
    for asset in (
        "app.js",
        "api.js",
        "dom.js",
        "svgplot.js",
        "uncertainty.js",
        "view_overview.js",
        "view_unit.js",
        "view_run.js",
        "style.css",
    ):
        r = client.get(f"/static/{asset}")
        assert r.status_code == 200 and len(r.content) > 500, asset
    # every module the page imports exists
    for name in ("./api.js", "./view_overview.js", "./view_unit.js", "./view_run.js"):
        assert name in client.get("/static/app.js").text


def test_series_need_a_viewer_token_and_name_what_is_missing(client: TestClient) -> None:
    assert client.get("/api/runs/run-new/plots/g-check").status_code == 401
    r = client.get("/api/runs/nope/plots/residuals", headers=VIEW)
    assert r.status_code == 404 and "nope" in r.json()["detail"]
    r = client.get("/api/runs/run-live/plots/allan", headers=VIEW)
    assert r.status_code == 409 and "running" in r.json()["detail"]
    r = client.get("/api/runs/run-gone/plots/g-check", headers=VIEW)
    assert r.status_code == 422 and "missing.csv" in r.json()["detail"]
    assert client.get("/api/units/NOPE/plots/history", headers=VIEW).status_code == 404


def test_g_check_after_matches_the_fit_and_an_explicit_inverse(
    client: TestClient, example: Path, contract: dict[str, Any]
) -> None:
    body = client.get("/api/runs/run-new/plots/g-check", headers=VIEW).json()
    after = np.array(body["after_m_s2"])
    assert len(body["labels"]) == after.size == 12
    g = body["g_local_m_s2"]
    assert g == pytest.approx(9.81535)
    # the contract's own summary of the same windows
    assert np.mean(after - g) == pytest.approx(contract["g_check"]["after"]["mean_error_m_s2"], abs=1e-12)
    assert np.std(after - g, ddof=1) == pytest.approx(contract["g_check"]["after"]["std_m_s2"], rel=1e-9)
    # K⁻¹ through an explicit inverse, on window means taken here from the segments
    rec = read_recording(example)
    Kinv = np.linalg.inv(np.array(contract["scale_matrix"]))
    segs = [s for s in rec.sidecar.segments or () if s.label in body["labels"]]
    means = np.array(
        [rec.accel_raw[(rec.t_s >= s.start_s) & (rec.t_s <= s.end_s)].mean(axis=0) for s in segs]
    )
    mags = np.linalg.norm((means - np.array(contract["bias"])) @ Kinv.T, axis=1)
    np.testing.assert_allclose(after, mags, rtol=1e-12)


def test_g_check_before_uses_the_previous_calibration_or_a_nominal_scale(client: TestClient) -> None:
    body = client.get("/api/runs/run-new/plots/g-check", headers=VIEW).json()
    assert body["before_label"] == "previous calibration (run-old)"
    # the previous K was 1 % high: every |f̂| is 1.01 times smaller, exactly
    np.testing.assert_allclose(np.array(body["before_m_s2"]) * 1.01, body["after_m_s2"], rtol=1e-12)
    oldest = client.get("/api/runs/run-old/plots/g-check", headers=VIEW).json()
    assert oldest["before_m_s2"] is None and oldest["before_label"] is None
    # a datasheet scale given in the query wins: |f̂| = |y − b0| / s
    r = client.get(
        "/api/runs/run-new/plots/g-check",
        headers=VIEW,
        params={"nominal_scale": 0.0177, "nominal_bias": [1.5, 1.5, 1.5]},
    )
    nominal = r.json()
    assert nominal["before_label"].startswith("nominal scale 0.0177")
    assert 9.0 < np.mean(nominal["before_m_s2"]) < 10.6
    bad = client.get("/api/runs/run-new/plots/g-check", headers=VIEW, params={"nominal_scale": 0.0})
    assert bad.status_code == 422 and "nominal_scale" in bad.json()["detail"]


def test_residuals_are_window_mean_minus_model(
    client: TestClient, example: Path, contract: dict[str, Any]
) -> None:
    body = client.get("/api/runs/run-new/plots/residuals", headers=VIEW).json()
    cal = calibrate_recording(read_recording(example))
    res = np.array(body["residual"])
    assert res.shape == (12, 3) and body["channels"] == ["ax", "ay", "az"]
    f = np.array([w.f_m_s2 for w in cal.windows])
    y = np.array([w.mean_raw for w in cal.windows])
    model = np.array(contract["bias"]) + f @ np.array(contract["scale_matrix"]).T
    np.testing.assert_allclose(res, y - model, atol=1e-12)
    z = np.array(body["normalized"], dtype=float)
    assert np.all(np.isfinite(z)) and np.max(np.abs(z)) < 5.0  # a clean recording: z-scores of order 1
    assert body["dof"] == 12 * 3 - 12


def test_allan_of_the_longest_static_window_is_served(client: TestClient) -> None:
    body = client.get("/api/runs/run-new/plots/allan", headers=VIEW).json()
    assert body["source"] == "longest static window" and body["unit"] == "V"
    taus = np.array(body["taus_s"])
    assert taus[0] == pytest.approx(0.1) and np.all(np.diff(taus) > 0)  # one sample at 10 Hz
    adev, lo, hi = (np.array(body[k]) for k in ("adev", "adev_lo", "adev_hi"))
    assert adev.shape == (3, taus.size) and np.all(lo <= adev) and np.all(adev <= hi)


def test_white_noise_allan_curve_follows_sigma_over_root_m() -> None:
    rng = np.random.default_rng(7)
    fs, sigma, n = 100.0, 2e-3, 40_000
    t = np.arange(n) / fs
    rec = Recording(Sidecar("SN-W", "V", fs, 9.81), t, 1.5 + sigma * rng.standard_normal((n, 3)))
    s, e, source = pick_noise_span(rec, [(10.0, 60.0), (100.0, 399.0)], [(0.0, 399.99)])
    assert (s, e, source) == (100.0, 399.0, "noise window")
    body = allan_series(rec, s, e, source)
    assert body["n_samples"] == 29_901
    expected = sigma / np.sqrt(np.array(body["taus_s"]) * fs)
    lo, hi = np.array(body["adev_lo"]), np.array(body["adev_hi"])
    inside = (lo <= expected) & (expected <= hi)
    assert inside.mean() > 0.55  # ±1σ intervals: about 68 % cover the truth
    assert np.allclose(np.array(body["adev"])[:, 0], sigma, rtol=0.02)
    with pytest.raises(ValueError, match=f"at least {MIN_ALLAN_SAMPLES}"):
        allan_series(rec, 1.0, 1.2, "noise window")
    with pytest.raises(ValueError, match="no noise or static window"):
        pick_noise_span(rec, [], [])


def test_coefficient_history_has_values_and_expanded_uncertainties(
    client: TestClient, contract: dict[str, Any]
) -> None:
    body = client.get(f"/api/units/{SERIAL}/plots/history", headers=VIEW).json()
    assert [r["run_id"] for r in body["runs"]] == ["run-old", "run-new", "run-gone"]
    assert {r["kind"] for r in body["runs"]} == {"other"}  # registered here, not by the service's runner
    by = {c["name"]: c for c in body["coefficients"]}
    assert len(by) == 12 and by["K_xy"]["unit"] == "V/(m/s²)"
    bx = by["bias_x"]
    assert bx["value"][1] == contract["bias"][0]
    assert bx["U"][1] == pytest.approx(2.0 * contract["bias_sigma"][0])
    assert bx["U"][0] == pytest.approx(4.0 * contract["bias_sigma"][0])  # run-old had 2σ stored
    assert by["K_zz"]["value"][0] == pytest.approx(1.01 * contract["scale_matrix"][2][2])


def test_history_skips_non_finite_values() -> None:
    nan = float("nan")
    good = stored_fit(bias=[1.0, 2.0, 3.0], bias_sigma=[0.1, 0.2, 0.3], scale_matrix=np.eye(3).tolist())
    bad = stored_fit(
        bias=[nan, 2.5, 3.5], bias_sigma=[0.1, nan, nan], scale_matrix=np.full((3, 3), nan).tolist()
    )
    out = coefficient_history(
        [HistoryPoint("b", "2026-02-01T00:00:00", bad), HistoryPoint("a", "2026-01-01T00:00:00", good)], "V"
    )
    assert [r["run_id"] for r in out["runs"]] == ["a", "b"]
    by = {c["name"]: c for c in out["coefficients"]}
    assert by["bias_x"]["run_index"] == [0] and by["bias_x"]["U"] == [pytest.approx(COVERAGE_K * 0.1)]
    assert by["bias_y"]["run_index"] == [0, 1] and by["bias_y"]["U"] == [pytest.approx(0.4), None]
    assert by["K_xx"]["value"] == [1.0] and by["K_xy"]["value"] == [0.0]


def test_a_stored_fit_with_a_renamed_key_is_named_by_the_history_and_the_export(
    tmp_path: Path, example: Path, contract: dict[str, Any]
) -> None:
    renamed = copy.deepcopy(contract)
    renamed["scale_matrix_1sigma"] = renamed.pop("scale_matrix_sigma")
    app = create_app(service_settings(tmp_path), start_scheduler=False)
    with TestClient(app) as c:
        _register(c, "run-a", RunState.COMPLETED, str(example), contract, 0.0)
        _register(c, "run-b", RunState.COMPLETED, str(example), renamed, 100.0)
        body = c.get(f"/api/units/{SERIAL}/plots/history", headers=VIEW).json()
        assert [r["run_id"] for r in body["runs"]] == ["run-a"]
        assert body["unreadable_fits"] == [
            {"run_id": "run-b", "error": "run run-b: stored fit: key 'scale_matrix_sigma' is missing"}
        ]
        bad = c.get("/api/runs/run-b/export/json", headers=VIEW)
        assert bad.status_code == 422
        assert bad.json()["detail"] == "run run-b: stored fit: key 'scale_matrix_sigma' is missing"
        good = c.get("/api/runs/run-a/export/json", headers=VIEW)
        assert good.status_code == 200
        doc = json.loads(good.text)
        assert doc["unit_serial"] == contract["unit"] and doc["scale_matrix"] == contract["scale_matrix"]


def test_diagnosis_route_says_why_there_is_none(client: TestClient) -> None:
    body = client.get("/api/runs/run-new/diagnosis", headers=VIEW).json()
    assert body["diagnosis"] is None and "no diagnosis stored" in body["note"]
    live = client.get("/api/runs/run-live/diagnosis", headers=VIEW).json()
    assert "running" in live["note"]


def test_bundle_cache_computes_once_for_concurrent_readers(example: Path, tmp_path: Path) -> None:
    cache = BundleCache(size=2)
    calls: list[int] = []
    real = build_bundle(str(example), [])

    def compute() -> Any:
        calls.append(1)
        time.sleep(0.2)
        return real

    key = ("r", str(example), 1, 1)
    got: list[Any] = []
    threads = [threading.Thread(target=lambda: got.append(cache.get(key, compute))) for _ in range(12)]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    assert len(calls) == 1 and len(got) == 12 and all(g is real for g in got)
    for k in range(3):  # least recently used entries leave
        cache.get(("other", k), lambda: real)
    assert len(cache) == 2 and cache.get(key, compute) is real and len(calls) == 2
    copy_path = tmp_path / "rec.csv"
    copy_path.write_text("t\n0\n")
    k1 = BundleCache.key("r", str(copy_path))
    copy_path.write_text("t\n0\n1\n")
    assert BundleCache.key("r", str(copy_path)) != k1  # a rewritten recording is a new key


def test_g_check_before_uses_the_units_registered_nominal(
    client: TestClient, example: Path, contract: dict[str, Any]
) -> None:
    """The plot's 'before' is the registered nominal the fit's own 'before' check used, not "no
    nominal is known" beside a fit that shows before values: |f̂| = |y − b0| / s per window."""
    sessions = client.app.state.services.sessions  # type: ignore[attr-defined]
    with sessions.begin() as s:
        unit = get_or_create_unit(s, "SN-DASH-NOM", channel_unit="V")
        unit.nominal_scale, unit.nominal_bias = 0.0178, 1.49
        create_run(s, "run-nom", unit.id, "static-12", recording_path=str(example))
        add_fit(s, "run-nom", "static", contract)
        finish_run(s, "run-nom", RunState.COMPLETED, outcome="PASS")
    body = client.get("/api/runs/run-nom/plots/g-check", headers=VIEW).json()
    assert body["before_label"].startswith("nominal scale 0.0178")
    rec = read_recording(example)
    segs = [w for w in rec.sidecar.segments or () if w.label in body["labels"]]
    means = np.array(
        [rec.accel_raw[(rec.t_s >= w.start_s) & (rec.t_s <= w.end_s)].mean(axis=0) for w in segs]
    )
    np.testing.assert_allclose(body["before_m_s2"], np.linalg.norm(means - 1.49, axis=1) / 0.0178, rtol=1e-12)


def test_the_raw_recording_is_downloaded_as_stored(client: TestClient, example: Path) -> None:
    csv = client.get("/api/runs/run-new/recording/csv", headers=VIEW)
    assert csv.status_code == 200 and csv.content == example.read_bytes()
    assert 'filename="run-new.csv"' in csv.headers["content-disposition"]
    sidecar = client.get("/api/runs/run-new/recording/sidecar", headers=VIEW)
    assert sidecar.status_code == 200 and sidecar.content == example.with_suffix(".json").read_bytes()
    assert client.get("/api/runs/run-new/recording/csv").status_code == 401
    r = client.get("/api/runs/run-new/recording/zip", headers=VIEW)
    assert r.status_code == 404 and "csv, sidecar" in r.json()["detail"]
    r = client.get("/api/runs/run-live/recording/csv", headers=VIEW)
    assert r.status_code == 409 and "still being written" in r.json()["detail"]
    r = client.get("/api/runs/run-gone/recording/csv", headers=VIEW)
    assert r.status_code == 422 and "missing.csv is not on this host" in r.json()["detail"]


def test_runs_are_searched_filtered_and_paged(client: TestClient) -> None:
    everything = [r["id"] for r in client.get("/api/runs", headers=VIEW, params={"limit": 1000}).json()]
    assert len(everything) >= 4
    # pages of two, newest first, together the whole list in order
    pages = [
        [r["id"] for r in client.get("/api/runs", headers=VIEW, params={"limit": 2, "offset": o}).json()]
        for o in range(0, len(everything), 2)
    ]
    assert [i for p in pages for i in p] == everything and all(len(p) <= 2 for p in pages)
    # text in the run id (case-insensitive), or in the serial; '_' and '%' are plain text
    found = client.get("/api/runs", headers=VIEW, params={"q": "RUN-NE"}).json()
    assert [r["id"] for r in found] == ["run-new"]
    by_serial = {r["id"] for r in client.get("/api/runs", headers=VIEW, params={"q": "dash-1"}).json()}
    assert {"run-old", "run-new", "run-live", "run-gone"} <= by_serial
    assert client.get("/api/runs", headers=VIEW, params={"q": "run_new"}).json() == []
    assert client.get("/api/runs", headers=VIEW, params={"q": "%"}).json() == []
    live = client.get("/api/runs", headers=VIEW, params={"state": "running", "procedure": "static-12"}).json()
    assert [r["id"] for r in live] == ["run-live"]
    assert client.get("/api/runs", headers=VIEW, params={"procedure": "rate-1axis"}).json() == []
    assert client.get("/api/runs", headers=VIEW, params={"offset": -1}).status_code == 422
    # an offset beyond a 64-bit integer is refused by name, not a 500 from the database driver
    for path in ("/api/runs", "/api/units"):
        huge = client.get(path, headers=VIEW, params={"offset": 2**64})
        assert huge.status_code == 422 and "offset" in huge.text, (path, huge.text)
        assert client.get(path, headers=VIEW, params={"offset": 2**53}).status_code == 200, path


def test_units_are_searched_and_paged(client: TestClient) -> None:
    for serial, model, customer in (
        ("UP-A1", "ADXL325", "Acme Lab"),
        ("UP-B2", "ADXL335", "Beta_Co"),
        ("up-c3", None, None),
    ):
        body = {"model": model, "customer_name": customer}
        r = client.put(f"/api/units/{serial}", json=body, headers=OP)
        assert r.status_code == 200, r.text
    everything = [u["serial"] for u in client.get("/api/units", headers=VIEW).json()]
    assert everything == sorted(everything) and {"UP-A1", "UP-B2", "up-c3"} <= set(everything)
    pages = [
        [u["serial"] for u in client.get("/api/units", headers=VIEW, params={"limit": 2, "offset": o}).json()]
        for o in range(0, len(everything), 2)
    ]
    assert [s for p in pages for s in p] == everything and all(len(p) <= 2 for p in pages)

    def found(q: str) -> list[str]:
        return [u["serial"] for u in client.get("/api/units", headers=VIEW, params={"q": q}).json()]

    assert found("up-") == ["UP-A1", "UP-B2", "up-c3"]  # case-insensitive, in serial order
    assert found("adxl335") == ["UP-B2"] and found("acme") == ["UP-A1"]  # model, customer
    assert found("beta_co") == ["UP-B2"] and found("a_m") == []  # '_' is plain text
    assert client.get("/api/units", headers=VIEW, params={"limit": 0}).status_code == 422

"""No placeholder goes out as a certificate: a real bench without the laboratory's identity or
the authorising person issues none; a simulated one says what is not configured; the settings
name each gap at start-up and in the health answer."""

from __future__ import annotations

from pathlib import Path

import pytest
from sqlalchemy.orm import Session

from bench.fitted_model import ContractError
from db.engine import make_session_factory
from db.migrate import open_database
from db.models import Run, RunState
from db.repo.results import add_fit, results_of_runs, set_diagnosis
from db.repo.runs import merge_params
from station.certificates.issue import CertificateRefused, issue_for_run
from station.settings import Settings, placeholder_reason
from tests.db._factories import make_run
from tests.station.certificates.test_certificate_conformity import CAL

IDENTITY = {
    "lab_name": "Acme Metrology",
    "lab_address": "1 Lab Road, Town",
    "lab_location": "Acme Metrology, room B12",
    "authorized_by": "A. Person",
}


def _completed_run(s: Session, run_id: str, *, sim: bool) -> None:
    run = make_run(s, run_id, state=RunState.COMPLETED)
    run.outcome = "PASS"
    merge_params(s, run_id, {"sim": {"seed": 1} if sim else None})
    add_fit(s, run_id, "static", CAL)
    s.flush()


def _sessions(tmp_path: Path):
    engine = open_database(f"sqlite:///{tmp_path / 'c.db'}")
    return engine, make_session_factory(engine)


def test_settings_name_each_missing_item_with_its_variable() -> None:
    blocking, warnings = Settings().certificate_gaps()
    assert [b.split("(")[-1] for b in blocking] == [
        "CALBENCH_LAB_NAME: it is empty)",
        "CALBENCH_LAB_ADDRESS: it is empty)",
        "CALBENCH_LAB_LOCATION: it is empty)",  # no default place of calibration
        "CALBENCH_AUTHORIZED_BY: it is empty)",
    ]
    assert any("CALBENCH_REFERENCE_EQUIPMENT" in w for w in warnings)
    full = Settings(
        **IDENTITY,
        reference_equipment="table T-3 s/n 42, cal. PTB-1, due 2027-03; DAQ s/n 7",
        ambient_conditions="(23 ± 2) °C",
    )
    assert full.certificate_gaps() == ([], [])
    assert full.reference_equipment == ["table T-3 s/n 42, cal. PTB-1, due 2027-03", "DAQ s/n 7"]


def test_a_real_bench_without_identity_issues_no_certificate_and_allocates_no_number(tmp_path: Path) -> None:
    engine, sessions = _sessions(tmp_path)
    try:
        with sessions.begin() as s:
            _completed_run(s, "r-real", sim=False)
        with sessions.begin() as s, pytest.raises(CertificateRefused) as info:
            issue_for_run(s, Settings(authorized_by="A. Person"), "r-real")
        msg = str(info.value)
        assert "CALBENCH_LAB_NAME" in msg and "CALBENCH_LAB_ADDRESS" in msg and "AUTHORIZED_BY" not in msg
        settings = Settings(
            **IDENTITY, reference_equipment="table T-3 s/n 42, due 2027-03", ambient_conditions="(23 ± 2) °C"
        )
        with sessions.begin() as s:
            cert = issue_for_run(s, settings, "r-real")
            c = cert.content
            assert cert.number.endswith("00001")  # the refusal used no number
        assert c["laboratory"] == {"name": "Acme Metrology", "address": "1 Lab Road, Town"}
        assert c["authorized_by"] == "A. Person"
        assert c["reference_equipment"] == ["table T-3 s/n 42, due 2027-03"]
        assert c["conditions"]["ambient"] == "(23 ± 2) °C"
        assert c["software"]["name"] == "calbench" and c["software"]["version"] != "not stated"
        assert c["item"]["nominal_scale"] == {"value": "not stated", "unit": ""}
    finally:
        engine.dispose()


def test_a_simulated_bench_issues_and_says_what_is_not_configured(tmp_path: Path) -> None:
    engine, sessions = _sessions(tmp_path)
    try:
        with sessions.begin() as s:
            _completed_run(s, "r-sim", sim=True)
            c = issue_for_run(s, Settings(), "r-sim").content
        assert c["laboratory"]["address"] == "not configured (CALBENCH_LAB_ADDRESS)"
        assert c["location"] == "not configured (CALBENCH_LAB_LOCATION)"
        assert c["authorized_by"] == "not configured (CALBENCH_AUTHORIZED_BY)"
        assert c["traceability"].startswith("SIMULATED BENCH")
        assert all("simulated" in e for e in c["reference_equipment"])
        after = c["g_check"]["after"]
        # no recording to count the windows of the |g| check: its U is not stated, never guessed
        assert after["n"] == "not stated" and after["expanded_uncertainty_m_s2"] == "not stated"
    finally:
        engine.dispose()


def test_health_names_the_gaps_and_the_preview_matches_the_procedure(tmp_path: Path) -> None:
    from fastapi.testclient import TestClient

    from api.main import create_app
    from bench.procedures import build_procedure, preview
    from tests.support.service_helpers import VIEW, service_settings

    settings = service_settings(tmp_path, sim_speed=4.0, lab_name="Acme Metrology")
    with TestClient(create_app(settings)) as client:
        health = client.get("/api/health").json()
        assert not health["certificates_blocked"]  # a simulated bench still issues, marked as such
        problems = " ".join(health["certificate_problems"])
        assert "CALBENCH_LAB_ADDRESS" in problems and "CALBENCH_AUTHORIZED_BY" in problems
        assert "CALBENCH_LAB_NAME" not in problems
        got = client.get("/api/procedures/static-12/preview", headers=VIEW).json()
        assert client.get("/api/procedures/nope/preview", headers=VIEW).status_code == 404
    pv = preview(build_procedure("static-12", dwell_s=3.0))
    assert got["n_windows"] == len(pv.windows) and got["n_poses"] == len(pv.poses_deg)
    assert got["dwell_s"] == 3.0 and got["dwell_source"] == "service setting"
    assert got["wall_duration_s"] == pytest.approx(pv.duration_s / 4.0)
    real = Settings(**IDENTITY)
    assert real.certificate_gaps()[0] == []


def test_a_stored_fit_without_its_g_check_is_refused_naming_the_key(tmp_path: Path) -> None:
    engine, sessions = _sessions(tmp_path)
    try:
        with sessions.begin() as s:
            _completed_run(s, "r-old", sim=True)
            add_fit(s, "r-old", "static", {**CAL, "g_check": {"before": CAL["g_check"]["after"]}})
        with sessions.begin() as s, pytest.raises(ContractError) as info:
            issue_for_run(s, Settings(**IDENTITY), "r-old")
        assert str(info.value) == "run r-old: stored fit: key 'g_check.after' is missing"
    finally:
        engine.dispose()


def test_stored_limit_checks_are_read_back_into_the_conformity_statement(tmp_path: Path) -> None:
    check = {"name": "bias_x", "unit": "V", "value": 1.54, "low": 1.45, "high": 1.55, "passed": True}
    engine, sessions = _sessions(tmp_path)
    try:
        with sessions.begin() as s:
            _completed_run(s, "r-lc", sim=True)
            run = s.get(Run, "r-lc")
            assert run is not None
            run.limit_checks = [check, {k: v for k, v in check.items() if k != "passed"}]
        with sessions.begin() as s, pytest.raises(ValueError) as info:
            issue_for_run(s, Settings(**IDENTITY), "r-lc")
        assert str(info.value) == "run r-lc: limit check 1: key 'passed' is missing"
        with sessions.begin() as s:
            run = s.get(Run, "r-lc")
            assert run is not None
            run.limit_checks = [check]
        with sessions.begin() as s:
            rows = issue_for_run(s, Settings(**IDENTITY), "r-lc").content["conformity"]["checks"]
        assert rows == [
            {
                "quantity": "bias_x",
                "value": 1.54,
                "expanded_uncertainty": 2e-05,  # the certificate's own U: 2 x bias_sigma_x of the fit
                "unit": "V",
                "low": 1.45,
                "high": 1.55,
                "acceptance_low": 1.45,
                "acceptance_high": 1.55,
                "verdict": "conforms",
            }
        ]
    finally:
        engine.dispose()


def test_a_stored_diagnosis_is_read_into_the_certificate_and_a_renamed_key_is_named(tmp_path: Path) -> None:
    from api.routes.views import run_out

    finding = {"effect": "lever_arm", "summary": "lever arm of 2 cm", "parameters": {"r_m": [0.02, 0.0, 0.0]},
               "sigma": {"r_m": [0.001, 0.001, 0.001]}, "delta_bic": -80.0}  # fmt: skip
    engine, sessions = _sessions(tmp_path)
    try:
        with sessions.begin() as s:
            _completed_run(s, "r-dg", sim=True)
            set_diagnosis(s, "r-dg", {"findings": [finding]}, None)
        with sessions.begin() as s:
            c = issue_for_run(s, Settings(**IDENTITY), "r-dg").content["diagnosis"]
            shown = run_out(s.get(Run, "r-dg"), "SN-0001", results=results_of_runs(s, ["r-dg"])["r-dg"])
        assert c["performed"] is True
        assert c["findings"] == [{k: finding[k] for k in ("effect", "summary", "parameters", "sigma")}]
        assert shown.n_findings == 1 and shown.diagnosis_note is None
        with sessions.begin() as s:
            _completed_run(s, "r-dg2", sim=True)
            set_diagnosis(s, "r-dg2", {"finding": [finding]}, None)
            results = results_of_runs(s, ["r-dg2"])["r-dg2"]
            shown = run_out(s.get(Run, "r-dg2"), "SN-0001", results=results, with_diagnosis=True)
        message = "run r-dg2: stored diagnosis: key 'findings' is missing"
        # the run's view shows no diagnosis and says why; the certificate is refused, naming the key
        assert (shown.n_findings, shown.diagnosis, shown.diagnosis_note) == (None, None, message)
        with sessions.begin() as s, pytest.raises(ContractError) as info:
            issue_for_run(s, Settings(**IDENTITY), "r-dg2")
        assert str(info.value) == message
    finally:
        engine.dispose()


@pytest.mark.parametrize(
    "value",
    ["address not configured", "not configured", "  Not Configured ", "TBD", "n/a", "-", "...",
     "<lab address>", "${CALBENCH_LAB_ADDRESS}", "CHANGEME", "placeholder address", "to be set"],
)  # fmt: skip
def test_placeholders_are_refused_like_empty_values(value: str) -> None:
    assert placeholder_reason(value) == f"{value.strip()!r} is a placeholder"
    blocking, _ = Settings(**{**IDENTITY, "lab_address": value}).certificate_gaps()
    assert blocking == [
        "the laboratory's address is not configured "
        f"(CALBENCH_LAB_ADDRESS: {value.strip()!r} is a placeholder)"
    ]


@pytest.mark.parametrize(
    "value", ["1 Lab Road, Town", "Testing Lab GmbH", "Unit 7, Sunset Blvd", "N. A. Smith"]
)
def test_real_entries_are_not_taken_for_placeholders(value: str) -> None:
    assert placeholder_reason(value) is None
    assert Settings(**{**IDENTITY, "lab_name": value, "authorized_by": value}).certificate_gaps()[0] == []


def test_the_compose_files_placeholders_issue_no_certificate_and_a_simulated_one_does_not_carry_them(
    tmp_path: Path,
) -> None:
    placeholders = {
        "lab_name": "calbench calibration laboratory",
        "lab_address": "address not configured",
        "authorized_by": "not configured",
    }
    settings = Settings(**placeholders)
    engine, sessions = _sessions(tmp_path)
    try:
        with sessions.begin() as s:
            _completed_run(s, "r-real", sim=False)
            _completed_run(s, "r-sim", sim=True)
        with sessions.begin() as s, pytest.raises(CertificateRefused) as info:
            issue_for_run(s, settings, "r-real")
        msg = str(info.value)
        for env in ("CALBENCH_LAB_ADDRESS", "CALBENCH_LAB_LOCATION", "CALBENCH_AUTHORIZED_BY"):
            assert env in msg
        assert "CALBENCH_LAB_NAME" not in msg  # a name that is no stand-in is accepted
        with sessions.begin() as s:
            c = issue_for_run(s, settings, "r-sim").content
        assert c["laboratory"]["address"] == "not configured (CALBENCH_LAB_ADDRESS)"
        assert c["authorized_by"] == "not configured (CALBENCH_AUTHORIZED_BY)"
    finally:
        engine.dispose()


def test_the_compose_file_leaves_the_laboratory_identity_to_be_set() -> None:
    compose = (Path(__file__).resolve().parents[3] / "docker-compose.yml").read_text()
    for env in (
        "CALBENCH_LAB_NAME",
        "CALBENCH_LAB_ADDRESS",
        "CALBENCH_LAB_LOCATION",
        "CALBENCH_AUTHORIZED_BY",
    ):
        line = next(x for x in compose.splitlines() if x.strip().startswith(f"{env}:"))
        assert f"${{{env}:?" in line, line  # required: compose refuses to start without it
        assert ":-" not in line, line  # no default stands in for it
    assert "bench room" not in compose

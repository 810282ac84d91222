"""A stored diagnosis is parsed once into typed findings; a missing or ill-typed key is named by
its dotted path, and a fresh diagnosis gives the same findings as its stored JSON."""

from __future__ import annotations

import json
from typing import Any

import numpy as np
import pytest

from bench.diagnosis.result import Diagnosis, Finding, ModelSummary
from bench.diagnosis.stored import StoredDiagnosis, StoredFinding
from bench.fitted_model import ContractError

# the example of docs/cli-contract.md
CONTRACT: dict[str, Any] = {
    "unit": "SN-0001",
    "baseline": {"terms": ["bias", "scale_matrix"], "residual_rms": 5.1e-5, "chi2_dof": 45.2, "bic": 1126.6},
    "findings": [
        {
            "effect": "nonlinearity_quadratic",
            "summary": "z channel: second-order nonlinearity of 1.5e-3 per g (1.5 mg at 1 g) "
            "left out of the model",
            "parameters": {"k2_per_g": [0.0, 0.0, 0.0015]},
            "sigma": {"k2_per_g": [0.0, 0.0, 0.00004]},
            "delta_bic": -1068.8,
            "residual_rms_after": 3.2e-6,
        }
    ],
    "final": {"terms": ["bias", "scale_matrix"], "residual_rms": 3.2e-6, "chi2_dof": 0.9, "bic": 57.8},
}
WHERE = "run R-9: stored diagnosis"


def _finding(effect: str, delta_bic: float) -> Finding:
    return Finding(
        effect=effect,
        summary=f"{effect} found",
        parameters={"r_m": [0.01, -0.02, 0.0]},
        sigma={"r_m": [0.001, 0.001, 0.001]},
        delta_bic=delta_bic,
        lr=55.0,
        residual_rms_after=2.5e-6,
        explanation="the physics",
        confounded_with=("proof_mass_offsets",),
    )


def test_the_contract_example_reads_back_as_typed_findings() -> None:
    d = StoredDiagnosis.from_contract(CONTRACT, WHERE)
    assert d == StoredDiagnosis(
        (
            StoredFinding(
                effect="nonlinearity_quadratic",
                summary=CONTRACT["findings"][0]["summary"],
                parameters={"k2_per_g": [0.0, 0.0, 0.0015]},
                sigma={"k2_per_g": [0.0, 0.0, 0.00004]},
                delta_bic=-1068.8,
                residual_rms_after=3.2e-6,
            ),
        )
    )
    assert StoredDiagnosis.from_contract({"findings": []}).findings == ()


def test_a_fresh_diagnosis_gives_what_its_stored_json_gives() -> None:
    summary = ModelSummary(("bias", "scale_matrix"), 1e-5, 1.0, 10.0, np.zeros((2, 3)), np.zeros((2, 3)))
    fresh = Diagnosis(
        unit="SN-1", channel_unit="V", method="static", baseline=summary, final=summary,
        findings=(_finding("lever_arm", -40.5), _finding("table_tilt", -12.25)),
        channel_ratio=np.ones(3), where="", correlations=(), unobservable={}, notes=(), noise_text="",
        labels=("a", "b"), mid_s=np.zeros(2), bias=np.zeros(3), K=np.eye(3),
    )  # fmt: skip
    stored_json = json.loads(json.dumps(fresh.to_contract()))
    assert StoredDiagnosis.of(fresh) == StoredDiagnosis.from_contract(stored_json)
    assert [f.effect for f in StoredDiagnosis.of(fresh).findings] == ["lever_arm", "table_tilt"]
    assert StoredDiagnosis.of(fresh).findings[1].delta_bic == -12.25


def _with(finding: dict[str, Any]) -> dict[str, Any]:
    return {**CONTRACT, "findings": [CONTRACT["findings"][0], finding]}


GOOD = CONTRACT["findings"][0]


def _without(key: str) -> dict[str, Any]:
    return _with({k: v for k, v in GOOD.items() if k != key})


@pytest.mark.parametrize(
    ("contract", "message"),
    [
        ({k if k != "findings" else "finding": v for k, v in CONTRACT.items()}, "key 'findings' is missing"),
        ({**CONTRACT, "findings": {"effect": "x"}}, "key 'findings' must be a list, got dict"),
        (["findings"], "the diagnosis must be an object, got list"),
        (_without("summary"), "key 'findings[1].summary' is missing"),
        (_with({**GOOD, "effect": 3}), "key 'findings[1].effect' must be a string, got int 3"),
        (_with({**GOOD, "parameters": [1.0]}), "key 'findings[1].parameters' must be an object, got list"),
        (_without("sigma"), "key 'findings[1].sigma' is missing"),
        (
            _with({k: v for k, v in GOOD.items() if k != "delta_bic"}),
            "key 'findings[1].delta_bic' is missing",
        ),
        (_with({**GOOD, "delta_bic": "-3"}), "key 'findings[1].delta_bic' must be a number or null, got str"),
        (
            _with({**GOOD, "residual_rms_after": True}),
            "key 'findings[1].residual_rms_after' must be a number",
        ),
        ({**CONTRACT, "findings": [GOOD, 7]}, "key 'findings[1]' must be an object, got int 7"),
    ],
)
def test_a_missing_or_ill_typed_key_is_named(contract: object, message: str) -> None:
    with pytest.raises(ContractError) as info:
        StoredDiagnosis.from_contract(contract, WHERE)
    assert str(info.value).startswith(f"{WHERE}: {message}")


def test_optional_numbers_may_be_null_or_absent() -> None:
    bare = {k: v for k, v in GOOD.items() if k != "residual_rms_after"}
    (f,) = StoredDiagnosis.from_contract({"findings": [{**bare, "delta_bic": None}]}).findings
    assert f.delta_bic is None and f.residual_rms_after is None

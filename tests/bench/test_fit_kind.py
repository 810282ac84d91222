"""The kind a stored fit states is the kind the fit chose: each fit's own ``calibrate --json``
object, read back by ``bench.fit_kind.contract_kind`` and parsed by ``FittedModel``."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from bench.fit_kind import FitKind, contract_kind, stated_kind
from bench.fitted_model import FittedModel
from tests.support.fits import DEFAULTS, calibration_result


@pytest.mark.parametrize("kind", [FitKind.STATIC, FitKind.ORIENTATION_FREE])
def test_a_fits_object_states_the_kind_it_chose(kind: FitKind) -> None:
    contract = json.loads(json.dumps(calibration_result(kind).to_contract()))  # as stored
    assert contract_kind(contract) is kind
    parsed = FittedModel.from_contract(contract)
    assert parsed.kind is kind


def test_a_moving_fit_is_stated_by_its_method() -> None:
    contract = {**DEFAULTS, "method": "dynamic-batch", "terms": ["bias", "scale_matrix", "time_skew"]}
    assert contract_kind(contract) is FitKind.MOVING
    parsed = FittedModel.from_contract(contract)
    assert parsed.kind is FitKind.MOVING


@pytest.mark.parametrize(
    ("method", "terms", "kind"),
    [
        (None, None, FitKind.STATIC),  # an object from before either key: the static fit's
        (None, "scale_matrix_lower_triangular", FitKind.STATIC),  # not a list of terms
        ("dynamic-batch", ["bias", "scale_matrix_lower_triangular"], FitKind.MOVING),
        (None, ("bias", "scale_matrix_lower_triangular"), FitKind.ORIENTATION_FREE),
    ],
)
def test_stated_kind_of_odd_objects(method: object, terms: object, kind: FitKind) -> None:
    assert stated_kind(method, terms) is kind


def test_naming_a_kind_loads_no_fit() -> None:
    """The migrations read kinds through ``bench.fit_kind``: it must not import numpy's fits."""
    probe = (
        "import sys, bench.fit_kind; "
        "print(sorted(m for m in sys.modules if m.startswith(('numpy', 'bench.'))))"
    )
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "['bench.fit_kind']"

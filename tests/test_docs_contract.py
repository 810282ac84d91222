"""docs/recording-format.md and docs/cli-contract.md say what the code does: the format's
example sidecar is read, the effect table is the catalogue with its parameter names, and the
JSON examples have the keys calbench prints (on the shipped examples)."""

from __future__ import annotations

import json
import re

from bench.calibration import calibrate_recording
from bench.calibration.diagnose import diagnose_recording
from bench.diagnosis.bench_families import FINDING_PARAMETERS
from bench.diagnosis.effects import EFFECTS
from bench.recording import read_recording
from bench.recording.sidecar import parse_sidecar
from tests.conftest import EXAMPLES, REPO_ROOT, STATIC_EXAMPLE

DOCS = REPO_ROOT / "docs"


def _json_blocks(text: str) -> list[str]:
    return re.findall(r"```json\n(.*?)```", text, flags=re.DOTALL)


def _section(text: str, heading: str) -> str:
    start = text.index(heading)
    nxt = text.find("\n#", start + len(heading))
    return text[start : nxt if nxt >= 0 else len(text)]


def test_the_formats_example_sidecar_is_a_valid_sidecar() -> None:
    (block,) = _json_blocks((DOCS / "recording-format.md").read_text())
    sc = parse_sidecar(json.loads(block), "recording-format.md")
    assert sc.unit_serial == "SN-0001" and sc.table is not None and len(sc.table.axes) == 3


def test_the_effect_table_is_the_catalogue_with_its_parameter_names() -> None:
    table = _section((DOCS / "cli-contract.md").read_text(), "### Effect ids and their parameters")
    rows = [line for line in table.splitlines() if line.startswith("| `")]
    documented = {re.match(r"\| `([a-z_]+)`", r).group(1): r.split("|")[3] for r in rows}  # type: ignore[union-attr]
    reported = {e.id: tuple(p.name for p in e.parameters) for e in EFFECTS} | FINDING_PARAMETERS
    assert set(documented) == set(reported)
    for effect, params in documented.items():
        for name in reported[effect]:
            assert f"`{name}`" in params, (effect, name)


def test_the_json_examples_have_the_keys_calbench_prints() -> None:
    text = (DOCS / "cli-contract.md").read_text()
    calibrate_doc, diagnose_doc = (json.loads(b) for b in _json_blocks(text)[:2])
    rec = read_recording(EXAMPLES / f"{STATIC_EXAMPLE}.csv")
    printed = calibrate_recording(rec, nominal_scale=0.0176, nominal_bias=[1.5, 1.5, 1.5]).to_contract()
    assert set(calibrate_doc) == set(printed)
    assert set(calibrate_doc["g_check"]) == set(printed["g_check"])
    diag = diagnose_recording(rec).to_contract()
    assert set(diagnose_doc) == set(diag) - {"unexplained"}  # present only when the model fails
    assert set(diagnose_doc["findings"][0]) == set(diag["findings"][0])
    assert set(diagnose_doc["mismatch"]) == set(diag["mismatch"])

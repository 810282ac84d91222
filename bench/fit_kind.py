"""The kinds of fit a recording gets, and how a stored fit states which one it is.

* :attr:`FitKind.MOVING`: the table turns while the DAQ samples: the sample-by-sample dynamic
  fit, p = 12 + extra terms;
* :attr:`FitKind.STATIC`: still windows whose specific force is known: the 12-parameter
  known-orientation fit;
* :attr:`FitKind.ORIENTATION_FREE`: still windows of unknown orientation: the 9-parameter fit
  of |f| = g (K as the lower-triangular L, K up to a rotation).

It is the one enum of fit kinds: the database's ``fit_model.kind`` column is of this type, and
the values are the strings that column has stored since migration 0001 (``static``, ``scalar``,
``dynamic``). The kind is chosen once, from the recording (:mod:`bench.calibration.kind`), and
carried by the fit. A fit kept as
its ``calbench calibrate --json`` object states its kind by two keys (docs/cli-contract.md):
``method`` ``"dynamic-batch"`` (:data:`DYNAMIC_BATCH`) for the moving fit, ``terms`` holding
``"scale_matrix_lower_triangular"`` (:data:`ORIENTATION_FREE_TERMS`) for the orientation-free
fit, neither for the static fit. :func:`stated_kind` reads them: the one place a kind is
recovered from a stored object (a parsed fit's :attr:`bench.fitted_model.FittedModel.kind`,
the migration that gave a fit stored in ``params`` its ``fit_model`` row).

This module imports nothing: a reader of stored fits (the database's migrations among them)
loads no fit to name a kind.
"""

from __future__ import annotations

from collections.abc import Mapping
from enum import StrEnum
from typing import Any

DYNAMIC_BATCH = "dynamic-batch"
"""The contract's ``method`` of a moving-table (sample-by-sample) fit."""
ORIENTATION_FREE_TERMS = ("bias", "scale_matrix_lower_triangular")
"""The contract's ``terms`` of an orientation-free fit (a static fit's: ``bias``, ``scale_matrix``)."""


class FitKind(StrEnum):
    """Which fit a recording gets (module docstring)."""

    STATIC = "static"
    ORIENTATION_FREE = "scalar"
    MOVING = "dynamic"

    @property
    def text(self) -> str:
        """The fit in words, as ``calbench calibrate`` states it."""
        return _TEXT[self]


_TEXT = {
    FitKind.STATIC: "known orientations, bias + full K",
    FitKind.ORIENTATION_FREE: "orientation-free |f| = g, K as L (K up to rotation)",
    FitKind.MOVING: "moving table, dynamic model over every sample",
}


def stated_kind(method: object, terms: object) -> FitKind:
    """The kind a fit's ``method`` and ``terms`` (as its contract object holds them) state:
    moving for ``method`` :data:`DYNAMIC_BATCH`, orientation-free for ``terms`` holding K as L,
    else static."""
    if method == DYNAMIC_BATCH:
        return FitKind.MOVING
    if isinstance(terms, list | tuple) and ORIENTATION_FREE_TERMS[1] in terms:
        return FitKind.ORIENTATION_FREE
    return FitKind.STATIC


def contract_kind(contract: Mapping[str, Any]) -> FitKind:
    """The kind a stored ``calbench calibrate --json`` object states (:func:`stated_kind` of its
    ``method`` and ``terms``; missing keys are a static fit's)."""
    return stated_kind(contract.get("method"), contract.get("terms"))

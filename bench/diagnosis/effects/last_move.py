"""``hysteresis``: the bias remembers the direction in which a table axis last turned.

Column for axis j on channel i: s_wj on channel i (``StaticEvidence.last_move_sign``: +1 / −1
the sign of the axis's last move before window w, 0 before it first moved), coefficient
h_ij in channel units: the window mean is b_i + h_ij after a positive move of axis j and
b_i − h_ij after a negative one. The pose is the same whichever way the table arrived, so
no term of the specific force, temperature or time holds it; on a 12-pose set the sign
pattern is partly a function of the poses, which is why it competes as a candidate in the
same selection (a catalogue or library look-alike otherwise takes the part it can mimic).
Candidates: every axis whose sign takes both values, on each channel.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from bench.diagnosis.effects.base import Candidate, EffectKind, FloatArray, ParamSpec, channel_column
from bench.diagnosis.evidence import StaticEvidence
from bench.diagnosis.thresholds import THRESHOLDS, Thresholds


@dataclass(frozen=True)
class LastMoveBias:
    """``hysteresis``: a bias step with the direction of an axis's last move (module docstring)."""

    id: str = "hysteresis"
    kind: EffectKind = "columns"
    needs_table: bool = True
    parameters: tuple[ParamSpec, ...] = (ParamSpec("half_step", "channel units", (-1, 3)),)
    explanation: str = (
        "the output remembers the direction of the table's last move (a flexure's or a cable's "
        "hysteresis, a fixture settling against its last push): the same pose reads differently "
        "after a positive and after a negative turn"
    )

    def observable(self, ev: StaticEvidence, th: Thresholds = THRESHOLDS) -> tuple[bool, str]:
        S = ev.last_move_sign
        if not ev.orientation_known or S is None:
            return False, "needs the table's moves between the windows (encoders)"
        if not any(np.any(S[:, j] > 0) and np.any(S[:, j] < 0) for j in range(S.shape[1])):
            return False, "no axis arrived at a window from both directions"
        return True, "axes that arrived at windows from both directions"

    def candidates(self, ev: StaticEvidence, th: Thresholds = THRESHOLDS) -> list[Candidate]:
        S = ev.last_move_sign
        assert S is not None
        k = S.shape[1]
        out = []
        for j in range(k):
            if not (np.any(S[:, j] > 0) and np.any(S[:, j] < 0)):
                continue
            for i in range(3):

                def cols(e: StaticEvidence, K: FloatArray, j: int = j, i: int = i) -> FloatArray:
                    assert e.last_move_sign is not None
                    return channel_column(e, i, e.last_move_sign[:, j])

                def params(
                    theta: FloatArray, cov: FloatArray, K: FloatArray, j: int = j, i: int = i
                ) -> tuple[dict[str, Any], dict[str, Any]]:
                    v = [[0.0] * 3 for _ in range(k)]
                    s = [[0.0] * 3 for _ in range(k)]
                    v[j][i], s[j][i] = float(theta[0]), float(np.sqrt(max(cov[0, 0], 0.0)))
                    return {"half_step": v}, {"half_step": s}

                out.append(
                    Candidate(
                        self.id,
                        f"{self.id}[axis {j + 1}, {'xyz'[i]}]",
                        (i,),
                        cols,
                        (f"half_step[{j}][{i}]",),
                        params,
                    )
                )
        return out


LAST_MOVE = LastMoveBias()

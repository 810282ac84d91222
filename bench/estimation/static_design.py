"""The design of the static 12-parameter fit: its parameter order, the rows H_w that map the
parameters to a window mean, and the check that a set of orientations identifies them.

Model (``static_fit``): y_w = b + K f_w + e_w = H_w θ + e_w with θ in the order of
:data:`PARAMETER_NAMES` and H_w = [I₃, I₃ ⊗ f_wᵀ] (3, 12). θ is identifiable iff the
(m, 4) design X = [1 f_x f_y f_z] has full column rank, i.e. the specific forces do not all
lie on one plane.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]

PARAMETER_NAMES: tuple[str, ...] = (
    "b_x", "b_y", "b_z",
    "K_xx", "K_xy", "K_xz",
    "K_yx", "K_yy", "K_yz",
    "K_zx", "K_zy", "K_zz",
)  # fmt: skip
"""Names of the 12 parameters in the order of ``StaticFit.cov``."""


_COLUMN_NAMES = ("bias", "K[:,0] (response to f_x)", "K[:,1] (response to f_y)", "K[:,2] (response to f_z)")
RCOND_LIMIT = 1e-6
"""Smallest singular value of the normalised design [1 f/|f|] relative to the largest."""


def _relation_text(v: FloatArray, f_scale: float) -> str:
    """Describe the null vector v of [1 f/f_scale] as the relation every window satisfies."""
    coef = v[1:] / f_scale
    k = int(np.argmax(np.abs(coef)))
    coef, const = coef / coef[k], -v[0] / coef[k]
    const = 0.0 if abs(const) < 1e-9 * f_scale else float(const)
    axes = ("f_x", "f_y", "f_z")
    terms = [
        f"{c:+.3g}·{axes[j]}" if j != k else axes[j] for j, c in enumerate(coef) if abs(c) > 1e-6 or j == k
    ]
    lhs = " ".join(terms) if len(terms) > 1 else terms[0]
    rhs = "0" if const == 0.0 else f"{const:+.4g} m/s²"
    return f"{lhs.replace('+1·', '+').replace('-1·', '-')} = {rhs}"


def check_design(f_m_s2: FloatArray) -> FloatArray:
    """Design matrix X = [1 f_x f_y f_z] (m, 4), refused if it cannot identify the parameters.

    The 12 parameters are identifiable iff X has full column rank 4, i.e. the specific
    forces do not all lie on one plane (a constant component is a plane too). The null
    space of the column-normalised X names the confounded parameters and the relation
    the orientations share.

    :param f_m_s2: (m, 3) specific force per window (m/s²).
    :returns: (m, 4) design matrix.
    :raises ValueError: fewer than 4 windows, or rank/conditioning too low; the message
        names the parameters that cannot be determined.
    """
    f = np.asarray(f_m_s2, dtype=float)
    m = f.shape[0]
    if m < 4:
        raise ValueError(f"at least 4 static windows with well-spread orientations are needed, got {m}")
    X = np.column_stack([np.ones(m), f])
    f_scale = float(np.median(np.linalg.norm(f, axis=1)))
    if not f_scale > 0:
        raise ValueError("specific force is zero in most windows: no gravity reference to calibrate against")
    Xn = np.column_stack([np.ones(m), f / f_scale])
    _, s, Vt = np.linalg.svd(Xn, full_matrices=False)
    null = Vt[s < RCOND_LIMIT * s[0]]
    if null.shape[0]:
        parts = []
        for v in null:
            names = [_COLUMN_NAMES[j] for j in np.flatnonzero(np.abs(v) > 0.05 * np.max(np.abs(v)))]
            joined = " and ".join(names)
            what = f"{joined} are confounded" if len(names) > 1 else f"{joined} cannot be determined"
            parts.append(f"{what}: every orientation has {_relation_text(v, f_scale)}")
        raise ValueError(
            "degenerate orientation set, the model cannot be identified on any channel: "
            + "; ".join(parts)
            + " (use ≥ 4 orientations whose gravity directions do not lie on one plane)"
        )
    return X


def design_rows(f: FloatArray) -> FloatArray:
    """(m, 3, 12) H_w = [I₃, I₃ ⊗ f_wᵀ]: y_w = H_w θ in the order of :data:`PARAMETER_NAMES`."""
    m = f.shape[0]
    H = np.zeros((m, 3, 12))
    for i in range(3):
        H[:, i, i] = 1.0
        H[:, i, 3 + 3 * i : 6 + 3 * i] = f
    return H

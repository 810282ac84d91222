"""calbench against real recordings calibrated by other people's tools (tests/data/real).

Each recording is converted with ``calbench convert`` into a temporary directory (nothing is
written beside the data), then calibrated, diagnosed (``calbench diagnose``, text and
``--json``) and analysed with ``calbench allan``. What is compared:

* imu_tk-xsens (Xsens MTi, 100 Hz, raw counts, 38 hand-placed still windows): IMU-TK's
  accelerometer model a = T·diag(k)·(y − b) (T upper-triangular, unit diagonal; Tedaldi et
  al. 2014, eq. 3-9) fitted by unweighted least squares of g − |a| on calbench's window
  means, as IMU-TK does with Ceres; its metric (T·diag(k))ᵀ(T·diag(k)) = (K Kᵀ)⁻¹ gives the
  lower-triangular L that calbench fits, so bias and L compare element by element.
* imucal-ferraris annotated session (204.8 Hz, counts): imucal's published result
  ``example_cal.json`` (u = b + K_a R_a a), against calbench's bias and K.
* imucal-ferraris example session (102.4 Hz, m/s²): imucal publishes no result for it; the
  row compares with Ferraris' closed form (imucal's equations 19-23) on the same window means.
* imu_utils-allan (six IMUs, Allan curves of ~2 h static records): calbench's five-term fit
  of each measured curve against the same fit of imu_utils' own fitted curve (N, B, K), and
  against its published acc_n (model at τ = 1 s) and acc_w (the model's floor).

Split halves: each recording calibrated on two disjoint window sets (odd / even windows,
first / second half of the run; or, with one window per pose, the first and second half of
every window), and the largest |difference| / √(σ₁² + σ₂²) over the parameters.

    python -m benchmarks.real_recordings [DATA_DIR]

DATA_DIR defaults to the repository's tests/data/real (each data set's README: source, licence).
"""

from __future__ import annotations

import csv
import dataclasses
import json
import re
import subprocess
import sys
import tempfile
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np

from bench.calibration import calibrate_recording
from bench.calibration.result import CalibrationResult
from bench.estimation.allan import edf_simple
from bench.estimation.noise_terms import fit_noise_model_curve, slope_method_curve
from bench.recording import Recording, Segment, read_recording, write_recording
from benchmarks.other_tools import ferraris_closed_form, imu_tk_fit, imu_tk_intervals

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_DATA = ROOT / "tests" / "data" / "real"
IMU_UTILS_RATE_HZ = {"xsens": 100.0, "16448": 200.0, "gx4": 500.0, "A3": 400.0, "N3": 400.0, "BMI160": 196.0}
IMU_UTILS_RECORD_S = 2 * 3600.0


def calbench(*args: str) -> str:
    """stdout of ``calbench ARGS`` (this checkout's code); raises on a non-zero exit."""
    out = subprocess.run(
        [sys.executable, "-m", "api", *args],
        capture_output=True,
        text=True,
        env={"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin"},
        check=False,
    )
    if out.returncode != 0:
        raise RuntimeError(f"calbench {' '.join(args)}: exit {out.returncode}: {out.stderr.strip()}")
    return out.stdout


def with_windows(
    rec: Recording, res: CalibrationResult, keep: list[int], half: int | None = None
) -> Recording:
    """The recording with its segments replaced by the fit's windows ``keep`` (indices);
    ``half`` 0 / 1 keeps only the first / second half of each window's samples."""
    segs = []
    for i in keep:
        w = res.windows[i]
        nominal = None if rec.sidecar.segments is None else _nominal(rec, w.label)
        start, end = w.start_s, w.end_s
        if half is not None:
            mid = 0.5 * (start + end)
            start, end = (start, mid) if half == 0 else (mid + 0.5 / rec.sidecar.sample_rate_hz, end)
        segs.append(Segment(start_s=start, end_s=end, label=w.label, nominal_up=nominal))
    return dataclasses.replace(rec, sidecar=dataclasses.replace(rec.sidecar, segments=tuple(segs)))


def _nominal(rec: Recording, label: str) -> str | None:
    return next((s.nominal_up for s in rec.sidecar.segments or () if s.label == label), None)


def params(res: CalibrationResult) -> tuple[np.ndarray, np.ndarray, tuple[str, ...]]:
    """Parameter vector, its one-sigma and names in the order of the fit's covariance."""
    names = res.parameter_names
    if res.kind.name == "ORIENTATION_FREE":
        K = res.K
        v = np.r_[res.bias, K[0, 0], K[1, 0], K[1, 1], K[2, 0], K[2, 1], K[2, 2]]
    else:
        v = np.r_[res.bias, res.K.ravel()]
    return v, np.sqrt(np.diag(res.cov)), names


def split_z(a: CalibrationResult, b: CalibrationResult) -> tuple[float, str, np.ndarray]:
    """Largest |Δ| / √(σa² + σb²) over the parameters, its name, and all of them."""
    va, sa, names = params(a)
    vb, sb, _ = params(b)
    z = (va - vb) / np.sqrt(sa**2 + sb**2)
    i = int(np.argmax(np.abs(z)))
    return float(abs(z[i])), names[i], z


def compare_rows(
    res: CalibrationResult, bias: np.ndarray, K: np.ndarray, who: str
) -> list[tuple[str, float, float, float, float]]:
    """(parameter, other tool, calbench, Δ in units, Δ / σ_calbench) for bias and K's diagonal."""
    rows = []
    for i, ax in enumerate("xyz"):
        d = res.bias[i] - bias[i]
        rows.append((f"b_{ax}", float(bias[i]), float(res.bias[i]), float(d), float(d / res.bias_sigma[i])))
    for i, ax in enumerate("xyz"):
        d = res.K[i, i] - K[i, i]
        rows.append(
            (f"K_{ax}{ax}", float(K[i, i]), float(res.K[i, i]), float(d), float(d / res.K_sigma[i, i]))
        )
    worst_off = max(
        (abs(res.K[i, j] - K[i, j]) / res.K_sigma[i, j], f"K_{'xyz'[i]}{'xyz'[j]}")
        for i in range(3)
        for j in range(3)
        if i != j and res.K_sigma[i, j] > 0
    )
    print(f"  {who}: largest off-diagonal |Δ|/σ {worst_off[0]:.2f} ({worst_off[1]})")
    return rows


def diagnose_check(path: Path) -> dict[str, Any]:
    """Findings of ``calbench diagnose`` (text and JSON) and whether the two agree."""
    text = calbench("diagnose", str(path))
    js = json.loads(calbench("diagnose", str(path), "--json"))
    n_found_text = len(re.findall(r"^FOUND ", text, flags=re.M))
    nowhere = "where: nowhere beyond the noise" in text
    found = [f["effect"] for f in js["findings"]]
    contradiction = (nowhere and bool(found)) or n_found_text != len(found)
    return {
        "findings": found,
        "where": js["mismatch"]["where"],
        "chi2_dof": js["mismatch"]["channels"],
        "text_json_agree": not contradiction,
    }


def allan_check(path: Path, window_s: tuple[float, float] | None = None) -> dict[str, Any]:
    """Stretch, lines and white-noise level of ``calbench allan --json`` (``--window-s`` if given)."""
    extra = () if window_s is None else ("--window-s", f"{window_s[0]:.6f}", f"{window_s[1]:.6f}")
    js = json.loads(calbench("allan", str(path), "--json", *extra))
    ch = js["noise_terms"]["channels"]
    return {
        "window": js["window"],
        "lines": js["lines"],
        "N": {c: (v["white_n"], v["white_n_sigma"]) for c, v in ch.items()},
        "warnings": len(js["warnings"]),
    }


def print_table(title: str, rows: list[tuple[str, float, float, float, float]], unit: str) -> None:
    print(
        f"\n{title}\n| parameter | other tool | calbench | Δ ({unit}) | Δ / σ_calbench |\n"
        "|---|---|---|---|---|"
    )
    for name, theirs, ours, d, z in rows:
        print(f"| {name} | {theirs:.6g} | {ours:.6g} | {d:+.3g} | {z:+.2f} |")


def print_splits(name: str, splits: dict[str, tuple[CalibrationResult, CalibrationResult]]) -> None:
    for what, (a, b) in splits.items():
        zmax, which, z = split_z(a, b)
        rms = float(np.sqrt(np.mean(z**2)))
        print(f"| {name} | {what} | {len(a.windows)} + {len(b.windows)} | {zmax:.2f} ({which}) | {rms:.2f} |")


def xsens(data: Path, tmp: Path) -> None:
    d = data / "imu_tk-xsens"
    out = tmp / "xsens.csv"
    calbench(
        "convert",
        "imu_tk",
        str(d / "xsens_acc.mat"),
        str(d / "xsens_gyro.mat"),
        "-o",
        str(out),
        "--channel-unit",
        "count",
        "--gyro-unit",
        "count",
        "--g-local-m-s2",
        "9.81744",
    )
    rec = read_recording(out)
    res = calibrate_recording(rec)
    y = np.array([w.mean_raw for w in res.windows])
    b, L = imu_tk_fit(y, rec.sidecar.g_local_m_s2)
    print(f"\n## imu_tk-xsens: {len(res.windows)} windows, calbench |g| rms {res.g_after.rms_m_s2:.3e} m/s²")
    print_table(
        "IMU-TK model (unweighted LSQ on the same window means) vs calbench (counts; L in counts per m/s²)",
        compare_rows(res, b, L, "IMU-TK"),
        "count",
    )
    readme_b = np.array([33124.0, 33275.0, 32364.0])
    readme_scale = np.array([0.002413, 0.002427, 0.002412])
    print(
        f"  README reference: bias Δ {np.round(res.bias - readme_b, 2)} counts (rounded to 1), "
        f"1/K_ii vs scale rel. Δ {np.round(1 / np.diag(res.K) / readme_scale - 1, 5)} (rounded to 4 digits)"
    )
    n = len(res.windows)
    halves = {
        "odd / even windows": ([i for i in range(n) if i % 2 == 0], [i for i in range(n) if i % 2 == 1]),
        "first / second half": (list(range(n // 2)), list(range(n // 2, n))),
    }
    splits = {
        k: (calibrate_recording(with_windows(rec, res, a)), calibrate_recording(with_windows(rec, res, c)))
        for k, (a, c) in halves.items()
    }
    theirs = imu_tk_intervals(rec.t_s, rec.accel_raw)
    rec_tk = dataclasses.replace(rec, sidecar=dataclasses.replace(rec.sidecar, segments=tuple(theirs)))
    splits["calbench's windows / IMU-TK's intervals (k = 6)"] = (res, calibrate_recording(rec_tk))
    print("\n| recording | split | windows | max |Δ|/σ | rms Δ/σ |\n|---|---|---|---|---|")
    print_splits("imu_tk-xsens", splits)
    report(out)
    allan_halves(out, res.windows[0].start_s, res.windows[0].end_s, float(np.mean(np.diag(res.K))))
    lines_on_real_noise(rec, tmp / "xsens_lines.csv", float(res.K[1, 1]))


def lines_on_real_noise(rec: Recording, path: Path, counts_per_m_s2: float) -> None:
    """The real recording with two lines added (a 0.5 Hz line of 3 counts on ax, a 23.4 Hz
    line of 12 mm/s² on ay): what ``calbench allan`` and ``calbench diagnose`` say of them."""
    t = rec.t_s
    a = rec.accel_raw.copy()
    injected = {"ax": (0.5, 3.0), "ay": (23.4, 12e-3 * counts_per_m_s2)}
    a[:, 0] += injected["ax"][1] * np.sin(2 * np.pi * 0.5 * t + 0.3)
    a[:, 1] += injected["ay"][1] * np.sin(2 * np.pi * 23.4 * t)
    write_recording(dataclasses.replace(rec, accel_raw=a), path, overwrite=True)
    al = allan_check(path)
    clean = allan_check(path.with_name("xsens.csv"))
    print("\nLines added to the real recording (counts): injected -> found by calbench allan")
    for ln in al["lines"]:
        f0, amp = injected.get(ln["channel"], (float("nan"), float("nan")))
        print(f"  {ln['channel']}: {f0} Hz, {amp:.3g} -> {ln['frequency_hz']:.4f} Hz, {ln['amplitude']:.3g}")
    for c in ("ax", "ay"):
        (v, sv), (v0, s0) = al["N"][c], clean["N"][c]
        z = (v - v0) / s0
        print(f"  N {c}: {v:.4g} ± {sv:.2g} with the lines, {v0:.4g} ± {s0:.2g} without ({z:+.2f} σ)")
    dg = diagnose_check(path)
    print(f"  diagnose: findings {dg['findings'] or 'none'}; where: {dg['where']}")


def allan_halves(path: Path, start_s: float, end_s: float, counts_per_m_s2: float) -> None:
    """The white-noise level N of the two halves of one still stretch, in units of their sigmas."""
    mid = 0.5 * (start_s + end_s)
    a, b = (allan_check(path, (lo, hi)) for lo, hi in ((start_s, mid), (mid, end_s)))
    print(f"\nAllan split halves of {start_s:.1f}-{end_s:.1f} s (N in counts·√s; m/s²/√Hz via mean K_ii):")
    print("| channel | N first half | N second half | |ΔN| / σ | N whole (m/s²/√Hz) |\n|---|---|---|---|---|")
    whole = allan_check(path, (start_s, end_s))
    for c in a["N"]:
        (va, sa), (vb, sb) = a["N"][c], b["N"][c]
        z = abs(va - vb) / float(np.hypot(sa, sb))
        n_si = whole["N"][c][0] / counts_per_m_s2
        print(f"| {c} | {va:.4g} ± {sa:.2g} | {vb:.4g} ± {sb:.2g} | {z:.2f} | {n_si:.3g} |")


def imucal(data: Path, tmp: Path) -> None:
    d = data / "imucal-ferraris"
    ann = tmp / "annotated.csv"
    calbench(
        "convert", "imucal", str(d / "annotated_session.csv"), "-o", str(ann), "--sample-rate-hz", "204.8"
    )
    rec = read_recording(ann)
    res = calibrate_recording(rec)
    cal = json.loads((d / "example_cal.json").read_text())
    KR = np.array(cal["K_a"]) @ np.array(cal["R_a"])
    print(f"\n## imucal annotated session: {len(res.windows)} windows")
    print_table(
        "imucal example_cal.json vs calbench (counts; K in counts per m/s²)",
        compare_rows(res, np.array(cal["b_a"]), KR, "imucal"),
        "count",
    )
    sess = tmp / "session.csv"
    calbench(
        "convert",
        "imucal",
        str(d / "example_ferraris_session.csv"),
        str(d / "example_ferraris_session_list.json"),
        "-o",
        str(sess),
        "--sample-rate-hz",
        "102.4",
    )
    rec2 = read_recording(sess)
    res2 = calibrate_recording(rec2)
    b2, K2 = ferraris_closed_form(np.array([w.mean_raw for w in res2.windows]), rec2.sidecar.g_local_m_s2)
    print("\n## imucal example session (102.4 Hz, m/s²)")
    print_table(
        "Ferraris closed form (imucal's algebra) on the same window means vs calbench (m/s²; K in 1)",
        compare_rows(res2, b2, K2, "Ferraris"),
        "m/s²",
    )
    print("\n| recording | split | windows | max |Δ|/σ | rms Δ/σ |\n|---|---|---|---|---|")
    for name, r, rs in (("imucal annotated", rec, res), ("imucal session", rec2, res2)):
        idx = list(range(len(rs.windows)))
        halves = (
            calibrate_recording(with_windows(r, rs, idx, 0)),
            calibrate_recording(with_windows(r, rs, idx, 1)),
        )
        print_splits(name, {"first / second half of every window": halves})
    report(ann)
    report(sess)


def report(path: Path) -> None:
    dg = diagnose_check(path)
    al = allan_check(path)
    n_txt = ", ".join(f"{c} {v:.3g} ± {s:.2g}" for c, (v, s) in al["N"].items())
    print(
        f"\n{path.name}: diagnose findings {dg['findings'] or 'none'}; where: {dg['where']}; "
        f"text and JSON agree: {dg['text_json_agree']}"
    )
    print(
        f"{path.name}: allan on {al['window']}; lines {al['lines'] or 'none'}; N {n_txt}; "
        f"model warnings {al['warnings']}"
    )


def imu_utils(data: Path) -> None:
    d = data / "imu_utils-allan"
    rows: dict[str, list[dict[str, str]]] = defaultdict(list)
    with (d / "imu_utils_allan_curves.csv").open() as fh:
        for row in csv.DictReader(fh):
            if row["quantity"] == "acc":
                rows[row["sensor"]].append(row)
    print("\n## imu_utils-allan, accelerometers (m/s²; N in m/s²/√Hz, B in m/s², K in m/s²/√s)")
    print(
        "calbench's 5-term fit of the measured curve vs the same fit of imu_utils' fitted curve; "
        "σ(1 s) and floor vs imu_utils' acc_n, acc_w"
    )
    print(
        "| sensor | axis | N ours ± σ | N theirs | z_N | B ours ± σ | B theirs | z_B | K ours ± σ | K theirs "
        "| z_K | σ(1 s)/acc_n | floor/acc_w | χ²/dof ours | N slope ± σ | z(N − N slope) "
        "| σ_gm ± σ | T_c (s) ± σ |\n" + "|---" * 18 + "|"
    )
    zs: list[float] = []
    for sensor, rs in rows.items():
        taus = np.array([float(r["tau_s"]) for r in rs])
        tau0 = 1.0 / IMU_UTILS_RATE_HZ[sensor]
        m = np.maximum(np.rint(taus / tau0).astype(int), 1)
        edf = np.array([edf_simple(round(IMU_UTILS_RECORD_S / tau0) + 1, int(k), 0) for k in m])
        text = (d / "original" / f"{sensor}_imu_param.yaml").read_text()
        for axis in "xyz":
            ours = fit_noise_model_curve(
                taus, np.array([float(r[f"adev_{axis}"]) for r in rs]), edf, tau0_s=tau0
            )
            theirs = fit_noise_model_curve(
                taus, np.array([float(r[f"fit_{axis}"]) for r in rs]), edf, tau0_s=tau0
            )
            block = text[text.index("Acc:") :]
            block = block[block.index(f"{axis}-axis:") :]
            acc_n = float(re.search(r"acc_n:\s*(\S+)", block).group(1))  # type: ignore[union-attr]
            acc_w = float(re.search(r"acc_w:\s*(\S+)", block).group(1))  # type: ignore[union-attr]
            cells = []
            for v, s, t in (
                (ours.white_n, ours.white_n_sigma, theirs.white_n),
                (ours.bias_instability_b, ours.bias_instability_b_sigma, theirs.bias_instability_b),
                (ours.rate_random_walk_k, ours.rate_random_walk_k_sigma, theirs.rate_random_walk_k),
            ):
                z = (v - t) / s if s > 0 else float("nan")
                zs.append(z)
                cells.append(f"{v:.3g} ± {s:.2g} | {t:.3g} | {z:+.1f}")
            r1 = float(ours.model_adev(1.0)) / acc_n
            rf = float(np.min(ours.model_adev(taus))) / acc_w
            sl = slope_method_curve(taus, np.array([float(r[f"adev_{axis}"]) for r in rs]), edf)
            z_sl = (ours.white_n - sl.white_n) / float(np.hypot(ours.white_n_sigma, sl.white_n_sigma))
            print(
                f"| {sensor} | {axis} | {' | '.join(cells)} | {r1:.3f} | {rf:.3f} | {ours.chi2_dof:.3g} "
                f"| {sl.white_n:.3g} ± {sl.white_n_sigma:.2g} | {z_sl:+.2f} "
                f"| {ours.gauss_markov_level:.3g} ± {ours.gauss_markov_level_sigma:.2g} "
                f"| {ours.gauss_markov_tc_s:.3g} ± {ours.gauss_markov_tc_s_sigma:.2g} |"
            )
    za = np.abs(np.array(zs))
    print(
        f"|z| over {za.size} terms: median {np.nanmedian(za):.2f}, > 2: {int(np.sum(za > 2))}, "
        f"> 3: {int(np.sum(za > 3))}"
    )


def main(argv: list[str]) -> int:
    data = Path(argv[0]) if argv else DEFAULT_DATA
    if not data.is_dir():
        print(f"{data}: no such directory (the real data sets are in tests/data/real)", file=sys.stderr)
        return 2
    with tempfile.TemporaryDirectory(prefix="calbench-real-") as tmp:
        xsens(data, Path(tmp))
        imucal(data, Path(tmp))
    imu_utils(data)
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))

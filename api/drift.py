"""Nightly drift checks: re-measure each unit of this bench and compare with its last certificate.

Test per coefficient c (the 3 biases and 9 elements of K):

    |Δc| > k · sqrt(u_cert(c)² + u_check(c)² + u_rep(c)²),   Δc = c_check − c_cert

with u_check the standard uncertainty of the check's fit (Type A) and u_cert the part of the
certificate's uncertainty that is not common to both runs. A certificate's u_c = U/k holds the
bench's Type B inputs (:data:`BENCH_COMMON_GROUPS`: table angle encoders, base levelling,
local gravity value, DAQ gain and offset); a check on the same bench measures through the
same encoders, base, g value and DAQ, so their errors are the same in both fits and cancel in
Δc (GUM 5.2: fully correlated inputs). On the same bench u_cert is therefore the root sum of
squares of the budget's other lines: the Type A line and the unit's temperature-coefficient
lines. Counting the common ones would widen a V unit's bias limit ≈ 2.5× (u_c 2.0e-5 V,
Type A 7.9e-6 V) and hide real drift below ≈ 0.4 mg. Without a budget the certificate's U/k
is Type A already; when the check ran on another bench (or the certificate's bench is not
known) nothing cancels and u_cert = U/k. u_rep is the unit's
run-to-run bias repeatability (biases only): each fit estimates the bias its own run saw,
which includes the run's mean of the slow bias wander (bias instability); no single run
can separate it, so neither fit's σ contains it, yet it differs between two runs of an
unchanged unit. Without it an ADXL-class unit (40 µg wander, 200 s correlation time) was
flagged in 13 % of unchanged pairs at a stated 3.2 % (tests/api/test_drift_false_alarm.py).
A unit is flagged when any coefficient exceeds its limit.

:class:`DriftScheduler` runs the check once a day at ``CALBENCH_DRIFT_TIME`` (``HH:MM``,
local time of the clock) for every unit of the bench that has a certificate, one after
the other on the bench's runner. Its clock is injectable and :meth:`DriftScheduler.tick`
is what its thread calls, so tests drive it without waiting for the night.
"""

from __future__ import annotations

import datetime as dt
import logging
import math
import threading
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np
import sqlalchemy as sa
from sqlalchemy.orm import Session, sessionmaker

from api.certificates.certificate import NOT_STATED
from api.runner import BenchBusy, BenchRunner
from api.settings import Settings
from bench.estimation.static_fit import PARAMETER_NAMES
from bench.records import RunRecord, utc_now
from db.models import Bench, Certificate, DriftCheck, Run, Unit
from db.repo.certificates import latest_certificate
from db.repo.drift import add_drift_check
from db.repo.units import get_bench_by_name, get_unit_by_serial

if TYPE_CHECKING:
    from api.run_queue import RunQueue

log = logging.getLogger(__name__)


def parse_time_of_day(text: str) -> dt.time | None:
    """``"HH:MM"`` -> ``time``; empty -> ``None`` (scheduler off).

    :raises ValueError: anything else, naming the setting.
    """
    if not text.strip():
        return None
    try:
        hh, mm = text.strip().split(":")
        return dt.time(int(hh), int(mm))
    except ValueError:
        raise ValueError(f"CALBENCH_DRIFT_TIME={text!r}: expected HH:MM (00:00..23:59) or empty") from None


BENCH_COMMON_GROUPS = ("table angle", "base levelling", "local gravity", "DAQ gain", "DAQ offset")
"""Budget groups (prefixes of ``TypeBInput.group``) whose errors are the same in every run on one
bench: the table's angle encoders and base, the local gravity value, the DAQ's gain and offset."""


def _bench_common(group: str) -> bool:
    return any(group.startswith(g) for g in BENCH_COMMON_GROUPS)


def reference_uncertainty(cert: dict[str, Any], name: str, *, same_bench: bool) -> tuple[np.ndarray, str]:
    """u_cert of ``"bias"`` (3,) or ``"scale_matrix"`` (3, 3) in the drift test, and its basis.

    Same bench with a budget: sqrt of the sum of squares of the budget's lines outside
    :data:`BENCH_COMMON_GROUPS` (Type A, temperature coefficients); otherwise U/k.

    :raises ValueError: the budget lacks one of the quantity's parameters.
    """
    q = cert["results"][name]
    u_k = np.asarray(q["expanded_uncertainty"], dtype=float) / float(q["k"])
    budget = cert["results"].get("uncertainty_budget")
    if not isinstance(budget, dict):
        return u_k, "U/k (the certificate states Type A only)"
    if not same_bench:
        return u_k, "U/k (Type A and Type B: the check ran on another bench, or the certificate's is unknown)"
    names = PARAMETER_NAMES[:3] if name == "bias" else PARAMETER_NAMES[3:]
    u = []
    for p in names:
        if p not in budget["quantities"]:
            raise ValueError(f"certificate budget has no {p!r}")
        lines = budget["quantities"][p]["contributions"]
        kept = [float(c["contribution"]) for c in lines if not _bench_common(str(c["group"]))]
        u.append(math.sqrt(sum(x**2 for x in kept)))
    basis = (
        "budget lines not common to both runs (Type A, temperature); same bench: "
        + ", ".join(BENCH_COMMON_GROUPS)
        + " cancel in the difference"
    )
    return np.array(u).reshape(u_k.shape), basis


def compare(
    cert: dict[str, Any],
    check: dict[str, Any],
    k: float,
    *,
    bias_repeatability: Any = None,
    same_bench: bool = False,
) -> dict[str, Any]:
    """Compare a check's fit (``calibrate --json``) with a certificate's content.

    :param bias_repeatability: (3,) standard deviation of the change of each channel's bias
        between two runs of an unchanged unit (channel units), or ``None`` (zero).
    :param same_bench: the check ran on the certificate's bench, so the bench-common Type B
        contributions of its budget cancel (:func:`reference_uncertainty`); ``False`` keeps U/k.

    :returns: ``{"k", "false_alarm_probability", "reference_uncertainty", "coefficients": [...],
        "flagged", "max_ratio"}`` (the probability that an unchanged unit is flagged, for
        independent normal errors; what u_reference contains and why); each coefficient has
        name, unit, reference, check, delta, u_reference, u_certificate (U/k), u_check,
        u_repeatability, limit, exceeded.
    :raises ValueError: a quantity missing or of another shape.
    """
    rows: list[dict[str, Any]] = []
    bases: dict[str, str] = {}
    u_rep_bias = np.zeros(3) if bias_repeatability is None else np.abs(np.asarray(bias_repeatability, float))
    if u_rep_bias.shape != (3,) or not np.all(np.isfinite(u_rep_bias)):
        raise ValueError(f"bias repeatability must be 3 finite values, got {bias_repeatability!r}")
    res = cert["results"]
    for name, sigma_key in (("bias", "bias_sigma"), ("scale_matrix", "scale_matrix_sigma")):
        q = res[name]
        ref = np.asarray(q["value"], dtype=float)
        u_cert = np.asarray(q["expanded_uncertainty"], dtype=float) / float(q["k"])
        u_ref, bases[name] = reference_uncertainty(cert, name, same_bench=same_bench)
        val = np.asarray(check[name], dtype=float)
        u_val = np.asarray(check[sigma_key], dtype=float)
        u_rep = u_rep_bias if name == "bias" else np.zeros_like(val)
        if ref.shape != val.shape or u_val.shape != val.shape:
            raise ValueError(f"{name}: certificate shape {ref.shape}, check shape {val.shape}")
        for idx in np.ndindex(ref.shape):
            delta = float(val[idx] - ref[idx])
            limit = k * math.hypot(float(u_ref[idx]), float(u_val[idx]), float(u_rep[idx]))
            rows.append({
                "name": f"{name}[{','.join(map(str, idx))}]",
                "unit": q["unit"],
                "reference": float(ref[idx]),
                "check": float(val[idx]),
                "delta": delta,
                "u_reference": float(u_ref[idx]),
                "u_certificate": float(u_cert[idx]),
                "u_check": float(u_val[idx]),
                "u_repeatability": float(u_rep[idx]),
                "limit": limit,
                "exceeded": abs(delta) > limit,
            })
    ratios = [abs(r["delta"]) / r["limit"] for r in rows if r["limit"] > 0]
    p_one = math.erfc(k / math.sqrt(2.0))  # P(|z| > k) for one unchanged coefficient
    return {
        "k": k,
        "false_alarm_probability": 1.0 - (1.0 - p_one) ** len(rows),
        "reference_uncertainty": {"same_bench": same_bench, **bases},
        "coefficients": rows,
        "flagged": any(r["exceeded"] for r in rows),
        "max_ratio": max(ratios) if ratios else None,
    }


def certificate_bench(s: Session, cert: Certificate) -> str | None:
    """The name of the bench a certificate's run was on: the content's ``bench``, else the run's
    bench row; ``None`` when neither states it."""
    name = cert.content.get("bench")
    if isinstance(name, str) and name.strip() and name != NOT_STATED:
        return name
    run = s.get(Run, cert.run_id)
    bench = s.get(Bench, run.bench_id) if run is not None and run.bench_id is not None else None
    return bench.name if bench is not None else None


def record_drift_check(s: Session, settings: Settings, serial: str, record: RunRecord) -> DriftCheck:
    """Store the drift check of ``serial`` from a finished check run (flagged or not).

    :raises LookupError: the unit is unknown.
    """
    unit = get_unit_by_serial(s, serial)
    if unit is None:
        raise LookupError(f"unit {serial} not found")
    cert = latest_certificate(s, unit.id)
    result: dict[str, Any] = {"procedure": record.start.procedure, "outcome": None, "status": "no_result"}
    flagged = False
    if record.outcome is not None:
        result["outcome"] = record.outcome.value
    if cert is None:
        result["error"] = "the unit has no certificate to compare with"
    elif record.calibration is None:
        result["error"] = record.error or "the check run produced no fit"
    else:
        check = dict(record.calibration)
        k_diag = np.abs(np.diag(np.asarray(check["scale_matrix"], dtype=float)))
        rep = k_diag * float(getattr(settings, "drift_bias_repeatability_m_s2", 0.0))
        cert_bench = certificate_bench(s, cert)
        same = cert_bench is not None and cert_bench == record.start.bench_name
        result = {
            **result,
            **compare(cert.content, check, settings.drift_k, bias_repeatability=rep, same_bench=same),
        }
        result["status"] = "compared"
        result["reference_number"] = cert.number
        result["reference_bench"], result["check_bench"] = cert_bench, record.start.bench_name
        flagged = bool(result["flagged"])
    return add_drift_check(
        s, unit.id, result, flagged, run_id=record.run_id,
        reference_certificate_id=cert.id if cert is not None else None,
    )


def units_due(s: Session, bench_name: str) -> list[str]:
    """Serials of this bench's units that have a certificate."""
    bench = get_bench_by_name(s, bench_name)
    if bench is None:
        return []
    stmt = (
        sa.select(Unit.serial)
        .where(Unit.bench_id == bench.id, sa.exists().where(Certificate.unit_id == Unit.id))
        .order_by(Unit.serial)
    )
    return list(s.scalars(stmt))


class DriftScheduler:
    """Starts the nightly check runs on the runner, one unit at a time.

    :param clock: wall clock (aware datetime); the run time is taken in the clock's local zone.
    :param poll_s: how often the thread calls :meth:`tick`.
    """

    def __init__(
        self,
        settings: Settings,
        sessions: sessionmaker[Session],
        runner: BenchRunner | RunQueue,
        clock: Callable[[], dt.datetime] = utc_now,
        poll_s: float = 20.0,
    ) -> None:
        self.settings, self.sessions, self.runner, self.clock = settings, sessions, runner, clock
        self.time_of_day = parse_time_of_day(settings.drift_time)
        self.poll_s = poll_s
        self.pending: list[str] = []
        self.last_run_at: dt.datetime | None = None
        self.next_run_at = self._next_after(clock()) if self.time_of_day else None
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def _next_after(self, now: dt.datetime) -> dt.datetime:
        assert self.time_of_day is not None
        local = now.astimezone()
        tod = self.time_of_day
        at = local.replace(hour=tod.hour, minute=tod.minute, second=0, microsecond=0)
        return at if at > local else at + dt.timedelta(days=1)

    def enqueue(self, serial: str | None = None) -> list[str]:
        """Queue one unit (it must exist) or every due unit of the bench; returns the queue.

        :raises LookupError: the unit is unknown.
        """
        with self.sessions.begin() as s:
            if serial is not None and get_unit_by_serial(s, serial) is None:
                raise LookupError(f"unit {serial} not found")
            serials = [serial] if serial is not None else units_due(s, self.settings.bench_name)
        with self._lock:
            self.pending.extend(x for x in serials if x not in self.pending)
            self.last_run_at = self.clock()
            return list(self.pending)

    def tick(self) -> str | None:
        """Queue the units when the time has come, and start the next check if the bench is
        free; returns the id of the run started, if any."""
        now = self.clock()
        if self.next_run_at is not None and now >= self.next_run_at:
            self.next_run_at = self._next_after(now)
            self.enqueue()
        with self._lock:
            if not self.pending or self.runner.current is not None:
                return None
            serial = self.pending[0]
        try:
            live = self.runner.start(
                serial, self.settings.drift_procedure, dwell_s=self.settings.drift_dwell_s, kind="drift_check"
            )
        except BenchBusy:
            return None
        with self._lock:
            if serial in self.pending:
                self.pending.remove(serial)
        return live.id

    def _loop(self) -> None:
        while not self._stop.wait(self.poll_s):
            try:
                self.tick()
            except Exception:  # keep the scheduler alive; the next tick tries again
                log.exception("drift scheduler tick failed")

    def start(self) -> None:
        """Start the scheduler's thread."""
        self._thread = threading.Thread(target=self._loop, name="drift-scheduler", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """Stop the thread (the current check run, if any, is the runner's)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)

"""The fixed wording of a calibration certificate (ISO/IEC 17025:2017 7.8): its title, the
uncertainty statements (GUM, coverage factor k), the items it must carry and where they are in
the content, the method descriptions, and what it says where the laboratory gave nothing."""

from __future__ import annotations

TITLE = "Calibration Certificate"
COVERAGE_K = 2.0
COVERAGE_STATEMENT = (
    "The reported expanded uncertainty is the combined standard uncertainty multiplied by the coverage "
    "factor k, which for a normal distribution corresponds to a coverage probability of approximately "
    "95 %; k = t_95.45 %(ν_eff) with the effective degrees of freedom ν_eff from the Welch–Satterthwaite "
    "formula, k = 2 for ν_eff = ∞. The standard uncertainty was determined in accordance with the GUM "
    "(JCGM 100:2008): Type A from the within-window noise of the recording (batch means) and the scatter "
    "between windows; Type B from the table angles, the levelling of the table base, the local gravity "
    "value, the DAQ gain and offset and the unit's temperature coefficients over the run's temperature "
    "changes, propagated by linearisation of the fit (uncertainty budget)."
)
DYNAMIC_COVERAGE_STATEMENT = COVERAGE_STATEMENT.replace(
    "Type A from the within-window noise of the recording (batch means) and the scatter between windows",
    "Type A from the sample noise of the moving-table fit and its correlation (sandwich covariance)",
).replace("propagated by linearisation of the fit", "propagated by refitting the changed recording")
"""The statement of a moving-table (``dynamic-batch``) fit with a budget."""
TYPE_A_ONLY_STATEMENT = (
    "The reported expanded uncertainty is the standard uncertainty multiplied by the coverage "
    "factor k = 2, which for a normal distribution corresponds to a coverage probability of "
    "approximately 95 %. The standard uncertainty was determined in accordance with the GUM "
    "(JCGM 100:2008): Type A only, from the within-window noise of the recording (batch means) and "
    "the scatter between windows; no Type B budget could be formed ({reason})."
)
REQUIRED_ITEMS = {
    "7.8.2.1 a title": "title",
    "7.8.2.1 b laboratory name": "laboratory.name",
    "7.8.2.1 b laboratory address": "laboratory.address",
    "7.8.2.1 c location": "location",
    "7.8.2.1 d unique identification": "number",
    "7.8.2.1 d end": "end",
    "7.8.2.1 e customer name": "customer.name",
    "7.8.2.1 e customer address": "customer.address",
    "7.8.2.1 f method": "method.description",
    "7.8.2.1 g item description": "item.description",
    "7.8.2.1 g item identification": "item.serial",
    "7.8.2.1 g item condition": "item.condition",
    "7.8.2.1 h date of receipt": "dates.received",
    "7.8.2.1 i date of calibration": "dates.calibration_start",
    "7.8.2.1 j date of issue": "dates.issued",
    "7.8.2.1 k sampling": "method.sampling",
    "7.8.2.1 l results relate to the item": "statements",
    "7.8.2.1 m results with units": "results.bias.unit",
    "7.8.2.1 n deviations": "method.deviations",
    "7.8.2.1 o authorisation": "authorized_by",
    "7.8.2.1 p external providers": "external_providers",
    "7.8.4.1 a uncertainty": "results.bias.expanded_uncertainty",
    "7.8.4.1 b conditions: temperature": "conditions.sensor_temperature",
    "7.8.4.1 b conditions: local g": "conditions.g_local_m_s2",
    "7.8.4.1 b conditions: ambient": "conditions.ambient",
    "7.8.4.1 c reference standards": "reference_equipment",
    "7.8.2.1 f software version": "software.version",
    "7.8.2.1 f procedure version": "method.procedure_version",
    "7.8.4.1 c traceability": "traceability",
    "7.8.4.1 d adjustment (none: results as found)": "item.adjustment",
    "7.8.4.1 d results with this calibration": "g_check.after",
    "7.5.1 who performed the run": "run_record.started_by",
    "7.8.4.1 e conformity": "conformity",
    "7.8.4.1 f opinions": "diagnosis.note",
}
"""Each ISO/IEC 17025:2017 item a certificate must carry, and where it is in the content
(dotted path); every one is filled, with :data:`NOT_STATED` where the laboratory gave nothing."""

SIMULATED_EQUIPMENT = (
    "simulated three-axis rate table (sim://, calbench's table simulator): no calibration status",
    "simulated DAQ (Modbus-TCP simulator): no calibration status",
)
SIMULATED_AMBIENT = "simulated bench: no ambient conditions"
NOT_STATED = "not stated"
"""What a certificate says where the laboratory did not give an item (never a null)."""
ONLY_ITEM = "The results relate only to the item calibrated."
RUN_MEAN_BIAS = (
    "The expanded uncertainty of the bias is that of the unit's mean bias over this run; it does not "
    "include how far the bias wanders from its long-run value between runs."
)
"""Said where the fit's bias sigma describes the run's mean bias (``bias_reference`` ``"run_mean"``)."""
NOT_REPRODUCED = (
    "This certificate shall not be reproduced except in full without the approval of the laboratory."
)
METHOD = {
    "static-12": "static multi-position (12 orientations, tumble test on a three-axis table, IEEE Std 1293 "
    "principle); per-channel weighted least squares of raw = b + K·f",
    "rate-1axis": "single-axis rate table; static poses for b and K, rate windows for the lever arm",
    "oscillation-2axis": "two-axis quasi-harmonic oscillation",
    "planned-static": "static multi-position, planned (12 orientations in antipodal order, repeated with "
    "short dwells, calbench plan); weighted least squares of raw = b + K·f with the wander between windows",
    "planned-tumble": "planned tumble (12 orientations in antipodal order, repeated with short dwells, "
    "calbench plan); dynamic model over every sample, moves included",
}

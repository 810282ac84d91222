"""A unit model's limits (the ``unit_limits.json`` form) for tests of the limit checks and of
the certificate's statement of conformity."""

SPEC = {
    "channel_unit": "V",
    "nominal_bias": [1.5, 1.5, 1.5],
    "bias_tolerance": 0.05,
    "nominal_scale": [0.02, 0.02, 0.02],
    "scale_tolerance_rel": 0.01,
    "cross_axis_max": 0.005,
    "g_error_after_max_m_s2": 0.004,
}

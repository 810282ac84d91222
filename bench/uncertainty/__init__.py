"""Measurement uncertainty of a calibration (GUM).

* ``budget``: Type A + Type B combination, sensitivities through the fit's own design, u_c,
  effective degrees of freedom and k (pure);
* ``type_a``: the static fit's Type A part with the Type B inputs' share of its
  between-window excess taken out (pure);
* ``inputs``: the Type B inputs of a static run: table angles, base levelling, local g, DAQ
  gain and offset, temperature (pure);
* ``dynamic``: the same budget for a moving-table fit, by central-difference refits of the
  changed recording (it calls the calibration, so it is not pure);
* ``drift``: the drift test between a certificate and a re-measurement (pure).
"""

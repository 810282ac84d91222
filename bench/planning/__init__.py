"""Planning a calibration: the procedure that reaches the wanted uncertainties in the least
table time, and how close it comes to what any motion could reach (docs/planning.md).

Pure parts (no procedures, no I/O): :mod:`~bench.planning.noise` (the unit's noise and the
covariance of window means it causes) and :mod:`~bench.planning.information` (the fit's
covariance for a design, the white-noise bound of any motion). :mod:`~bench.planning.search`
builds candidate procedures, times them on the table's limits and picks the shortest that
meets the targets.
"""

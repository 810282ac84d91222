"""Benchmarks: ``make bench`` runs every ``benchmarks/bench_*.py`` module's ``main()``.

Each benchmark times calbench against a baseline in the same run and prints ratios,
not absolute times alone (these machines are noisy).
"""

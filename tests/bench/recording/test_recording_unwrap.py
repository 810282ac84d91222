"""Encoder angles unwrapped chunk by chunk are numpy.unwrap's, bit for bit, wherever a chunk ends."""

from __future__ import annotations

import numpy as np
import pytest

from bench.recording import model


def wrapped_walk(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """(true angles, the same wrapped to [-π, π)) of a 3-axis random walk with steps of exactly ±π."""
    rng = np.random.default_rng(seed)
    steps = rng.normal(0.0, 0.8, (n, 3))
    for sign in (1.0, -1.0):
        steps[rng.integers(1, n, 20), rng.integers(0, 3, 20)] = sign * np.pi
    q = np.cumsum(steps, axis=0)
    return q, (q + np.pi) % (2.0 * np.pi) - np.pi


@pytest.mark.parametrize("chunk", [1, 2, 7, 1000, 5000])
def test_chunked_unwrap_is_numpys(monkeypatch: pytest.MonkeyPatch, chunk: int) -> None:
    monkeypatch.setattr(model, "UNWRAP_CHUNK", chunk)
    _, w = wrapped_walk(4001, seed=chunk)
    np.testing.assert_array_equal(model.unwrap_rad(w.copy()), np.unwrap(w, axis=0))


def test_unwrap_recovers_a_turning_table(monkeypatch: pytest.MonkeyPatch) -> None:
    """Independently of numpy: an axis turning 3.7 turns at < π per sample comes back continuous."""
    monkeypatch.setattr(model, "UNWRAP_CHUNK", 64)
    q = np.column_stack(
        [np.linspace(0.0, 3.7 * 2.0 * np.pi, 1001), np.zeros(1001), -np.linspace(0, 9.0, 1001)]
    )
    w = (q + np.pi) % (2.0 * np.pi) - np.pi
    np.testing.assert_allclose(model.unwrap_rad(w), q, atol=1e-12)


def test_one_sample_and_no_samples_are_unchanged() -> None:
    one = np.array([[3.0, -3.0]])
    np.testing.assert_array_equal(model.unwrap_rad(one.copy()), one)
    assert model.unwrap_rad(np.zeros((0, 2))).shape == (0, 2)

"""Counting the calls of a function wherever it is imported (a test of how often a run reads or
fits its recording)."""

from __future__ import annotations

import sys
from collections import Counter
from collections.abc import Callable
from typing import Any

import pytest


def count_everywhere(monkeypatch: pytest.MonkeyPatch, calls: Counter[str], module: Any, name: str) -> None:
    """Count the calls of ``module.name`` in ``calls[name]`` under every name it is imported as
    (any loaded module holding the same function, and the lazy imports that fetch it from its
    module later)."""
    original: Callable[..., Any] = getattr(module, name)

    def counted(*args: Any, **kwargs: Any) -> Any:
        calls[name] += 1
        return original(*args, **kwargs)

    for mod in list(sys.modules.values()):
        if mod is not None and getattr(mod, name, None) is original:
            monkeypatch.setattr(mod, name, counted)

"""Failed authentications counted per client, so secrets cannot be guessed at the rate the
service answers.

:class:`FailedAuthLimiter` keeps, per client address, the times of its failed authentications
(answers 401 to a request that presented a token or a signed link) within a sliding window of
:data:`AUTH_FAILURE_WINDOW_S`; at :data:`MAX_AUTH_FAILURES` of them the request guard
(:class:`api.guard.RequestGuard`) answers every request of that client that carries a
credential 429 with ``Retry-After``: the time until the oldest failure leaves the window.
"""

from __future__ import annotations

import collections
import threading
import time
from collections.abc import Callable

MAX_AUTH_FAILURES = 20
"""Failed authentications (401) of one client within :data:`AUTH_FAILURE_WINDOW_S` before its
requests with a credential are answered 429."""
AUTH_FAILURE_WINDOW_S = 60.0


class FailedAuthLimiter:
    """Failed authentications per client address in a sliding window (thread-safe).

    :param limit: failures allowed within ``window_s``; :param clock: monotonic time (s), for tests.
    """

    def __init__(
        self,
        limit: int = MAX_AUTH_FAILURES,
        window_s: float = AUTH_FAILURE_WINDOW_S,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.limit, self.window_s, self._clock = limit, window_s, clock
        self._failures: dict[str, collections.deque[float]] = {}
        self._lock = threading.Lock()

    def _recent(self, client: str, now: float) -> collections.deque[float]:
        q = self._failures.setdefault(client, collections.deque())
        while q and now - q[0] > self.window_s:
            q.popleft()
        return q

    def failed(self, client: str) -> None:
        """Count one failed authentication of ``client``."""
        with self._lock:
            now = self._clock()
            self._recent(client, now).append(now)
            if len(self._failures) > 10_000:  # forget clients with no recent failure
                for key in [k for k, q in self._failures.items() if not q or now - q[-1] > self.window_s]:
                    del self._failures[key]

    def retry_after_s(self, client: str) -> float | None:
        """Seconds until ``client`` may try again, or ``None`` when it is under the limit."""
        with self._lock:
            now = self._clock()
            q = self._recent(client, now)
            if len(q) < self.limit:
                return None
            return max(1.0, self.window_s - (now - q[0]))

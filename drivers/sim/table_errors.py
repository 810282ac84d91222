"""The simulated controller's refusals and its SCPI error queue."""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

from drivers.table_protocol import ScpiError

ERROR_QUEUE_SIZE = 10


class Rejected(Exception):
    """A refused command: SCPI ``code`` (< 0), or axis code n (2…12) with ``axis`` (1 = outermost)."""

    def __init__(self, code: int, text: str, axis: int | None = None) -> None:
        self.code = int(code)
        self.text = text
        self.axis = axis
        super().__init__(f"{code} {text}" + (f" (axis {axis})" if axis is not None else ""))


@dataclass(frozen=True)
class QueuedError:
    """One error-queue entry; ``axis`` (1 = outermost) is set for axis codes."""

    code: int
    text: str
    axis: int | None = None


class ErrorQueue:
    """FIFO of ``ERROR_QUEUE_SIZE`` entries; when full the newest entry becomes −350 (SCPI)."""

    def __init__(self, size: int = ERROR_QUEUE_SIZE) -> None:
        self.size = size
        self._entries: deque[QueuedError] = deque()

    def push(self, entry: QueuedError) -> None:
        if len(self._entries) >= self.size:
            self._entries[-1] = QueuedError(ScpiError.QUEUE_OVERFLOW, "Queue overflow")
        else:
            self._entries.append(entry)

    def pop(self) -> QueuedError | None:
        """Oldest entry, ``None`` when empty."""
        return self._entries.popleft() if self._entries else None

    def __len__(self) -> int:
        return len(self._entries)

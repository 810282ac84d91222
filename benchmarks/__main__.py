"""Run every benchmark module, or the ones named on the command line (``python -m benchmarks allan``);
with ``--record`` (what ``make bench`` does) each one's output replaces its block in
docs/benchmarks.md (:mod:`benchmarks.record`)."""

from __future__ import annotations

import contextlib
import datetime as dt
import importlib
import io
import os
import pkgutil
import sys
import time

import benchmarks
from benchmarks.record import record


class _Tee(io.StringIO):
    """Standard output that is also kept."""

    def write(self, s: str) -> int:
        sys.__stdout__.write(s)
        sys.__stdout__.flush()
        return super().write(s)


def main(argv: list[str]) -> int:
    """Import and run ``main()`` of each ``bench_*`` module; return 1 if any raised."""
    keep = "--record" in argv
    argv = [a for a in argv if a != "--record"]
    names = sorted(m.name for m in pkgutil.iter_modules(benchmarks.__path__) if m.name.startswith("bench_"))
    if argv:
        names = [n for n in names if any(a in n for a in argv)]
    failed = 0
    for name in names:
        print(f"\n=== {name} ===", flush=True)
        t0 = time.perf_counter()
        out = _Tee()
        ok = True
        try:
            with contextlib.redirect_stdout(out):
                importlib.import_module(f"benchmarks.{name}").main()
        except Exception as exc:  # report and go on with the other benchmarks
            failed += 1
            ok = False
            print(f"FAILED: {type(exc).__name__}: {exc}")
        elapsed = time.perf_counter() - t0
        print(f"({elapsed:.1f} s)")
        if keep and ok:  # a failed benchmark leaves its recorded figures as they were
            record(name, out.getvalue(), elapsed, dt.date.today().isoformat(), os.getloadavg()[0])
            print("(recorded in docs/benchmarks.md)")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

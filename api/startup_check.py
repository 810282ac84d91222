"""The service's configuration, checked once at start-up with one clear line per problem.

Without this a bad device URL is found only when the first run opens the devices, and a
zero-length SQLite file (a truncated copy, a full disk) is silently taken for a new, empty
database. :func:`check_configuration` raises :class:`ConfigError` (a ``ValueError``) naming the
setting (its ``CALBENCH_*`` variable), the value, and what was expected.
"""

from __future__ import annotations

import math
import urllib.parse
from pathlib import Path

from sqlalchemy.engine import make_url

from bench.inputs import InputError, check_text
from drivers.factory import TABLE_OPENERS, parse_sim_url, url_scheme
from station.settings import Settings

SQLITE_MAGIC = b"SQLite format 3\x00"
MIN_RUN_DWELL_S = 0.5
"""Shortest static dwell (s) a service may be configured with (as ``RunCreate.dwell_s``)."""


class ConfigError(ValueError):
    """A setting the service cannot start with."""


def _check_table_url(url: str) -> None:
    scheme = url_scheme(url)
    if scheme == "sim":
        try:
            parse_sim_url(url)
        except ValueError as exc:
            raise ConfigError(f"CALBENCH_TABLE_URL: {exc}") from None
        return
    if scheme not in TABLE_OPENERS:
        known = ", ".join(f"{s}://" for s in sorted(TABLE_OPENERS) if s)
        raise ConfigError(
            f"CALBENCH_TABLE_URL {url!r}: unknown scheme {scheme!r}; "
            f"expected sim://, {known} or a device path"
        )
    if scheme == "socket":
        parts = urllib.parse.urlsplit(url)
        try:
            port = parts.port
        except ValueError:
            port = None
        if not parts.hostname or port is None:
            raise ConfigError(f"CALBENCH_TABLE_URL {url!r}: expected socket://host:port")


def _check_daq_url(url: str, table_url: str) -> None:
    scheme = url_scheme(url)
    if scheme == "sim":
        if url_scheme(table_url) != "sim":
            raise ConfigError(f"CALBENCH_DAQ_URL {url!r}: a simulated DAQ needs CALBENCH_TABLE_URL=sim://")
        return
    if scheme != "modbus-tcp":
        raise ConfigError(
            f"CALBENCH_DAQ_URL {url!r}: unknown scheme {scheme!r}; expected modbus-tcp://host:port"
        )
    parts = urllib.parse.urlsplit(url)
    try:
        parts.port  # noqa: B018 - parsing it is the check
    except ValueError:
        raise ConfigError(f"CALBENCH_DAQ_URL {url!r}: the port is not 1..65535") from None
    if not parts.hostname:
        raise ConfigError(f"CALBENCH_DAQ_URL {url!r}: no host; expected modbus-tcp://host:port")
    if url_scheme(table_url) == "sim":
        raise ConfigError(
            f"CALBENCH_DAQ_URL {url!r}: the table is simulated (CALBENCH_TABLE_URL=sim://), the DAQ is not"
        )


def _check_database(settings: Settings) -> None:
    url = make_url(settings.effective_database_url)
    if url.get_backend_name() != "sqlite" or not url.database or url.database == ":memory:":
        return
    path = Path(url.database)
    if not path.exists():
        return
    if not path.is_file():
        raise ConfigError(f"database {path}: not a file")
    with path.open("rb") as f:
        head = f.read(len(SQLITE_MAGIC))
    if not head:
        raise ConfigError(
            f"database {path} is an empty (zero-length) file, not a database: a truncated copy or a "
            "full disk? Restore it from a backup, or remove it to start a new, empty database"
        )
    if head != SQLITE_MAGIC:
        raise ConfigError(f"database {path} is not an SQLite database (its first bytes are {head[:8]!r})")


def _check_texts(settings: Settings) -> None:
    for name in ("lab_name", "lab_location", "authorized_by", "customer_name", "bench_name"):
        try:
            check_text(getattr(settings, name))
        except InputError as exc:
            raise ConfigError(f"CALBENCH_{name.upper()}: {exc}") from None
    for name in ("lab_address", "customer_address"):
        try:
            check_text(getattr(settings, name), multiline=True)
        except InputError as exc:
            raise ConfigError(f"CALBENCH_{name.upper()}: {exc}") from None


def check_configuration(settings: Settings) -> None:
    """Check device URLs, the database file, the run dwell and the certificate texts.

    Nothing is opened or connected: a device that is switched off is no configuration error.

    :raises ConfigError: one line naming the setting, its value and what was expected.
    """
    if not settings.sim:
        _check_table_url(settings.table_url)
        if settings.daq_url is not None:
            _check_daq_url(settings.daq_url, settings.table_url)
        elif url_scheme(settings.table_url) != "sim":
            raise ConfigError(
                f"CALBENCH_DAQ_URL is not set; the table {settings.table_url!r} is real, so the DAQ's "
                "modbus-tcp://host:port is needed"
            )
    if settings.run_dwell_s is not None and not (
        math.isfinite(settings.run_dwell_s) and MIN_RUN_DWELL_S <= settings.run_dwell_s <= 3600.0
    ):
        raise ConfigError(
            f"CALBENCH_RUN_DWELL_S {settings.run_dwell_s!r}: expected {MIN_RUN_DWELL_S}..3600 s"
        )
    for name in ("sim_speed", "sim_sample_rate_hz", "drift_dwell_s"):
        value = getattr(settings, name)
        if not (math.isfinite(value) and value > 0):
            raise ConfigError(f"CALBENCH_{name.upper()} {value!r}: expected a positive number")
    _check_database(settings)
    _check_texts(settings)

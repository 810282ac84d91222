"""Credentials kept out of the access log.

A signed link (``?link=``), or a token a client put in a URL's query although it is not
accepted there, would reach the access log with the URL. :func:`redact_url` replaces the
values of the ``access_token``, ``link`` and ``token`` query parameters by ``REDACTED``;
:class:`RedactSecrets` is the logging filter that applies it to every record of the access
logger, installed by :func:`install_log_redaction`.
"""

from __future__ import annotations

import logging
import re

_SECRET_QUERY = re.compile(r"((?:^|[?&])(?:access_token|link|token)=)[^&#\s]*", re.IGNORECASE)


def redact_url(url: str) -> str:
    """``url`` with the values of ``access_token``, ``link`` and ``token`` query parameters replaced
    by ``REDACTED``."""
    return _SECRET_QUERY.sub(r"\1REDACTED", url)


class RedactSecrets(logging.Filter):
    """Access-log filter: a credential in a URL's query (a signed link, or a token a client put
    there although it is not accepted) never reaches the log. Install it on ``uvicorn.access``."""

    def filter(self, record: logging.LogRecord) -> bool:
        if isinstance(record.args, tuple):
            record.args = tuple(redact_url(a) if isinstance(a, str) else a for a in record.args)
        elif isinstance(record.msg, str):
            record.msg = redact_url(record.msg)
        return True


def install_log_redaction(logger_name: str = "uvicorn.access") -> None:
    """Add :class:`RedactSecrets` to the access logger (once)."""
    logger = logging.getLogger(logger_name)
    if not any(isinstance(f, RedactSecrets) for f in logger.filters):
        logger.addFilter(RedactSecrets())

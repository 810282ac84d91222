"""Bearer tokens with roles: ``viewer`` reads, ``operator`` also writes, ``admin`` also manages.

Tokens come from ``CALBENCH_TOKENS`` (``operator:SECRET[:NAME],viewer:SECRET,...``; NAME is
the operator the token stands for) and from the ``api_token`` table (only their SHA-256 is
stored, with the operator's name); a run's audit trail names the operator of every request.
A request presents one as ``Authorization: Bearer SECRET``. A secret never goes into a URL
(it would land in access logs and browser history): the two endpoints a browser opens
directly (the event stream, the PDF) also accept ``?link=``, a short-lived link signed by the
service for one path (:class:`LinkSigner`, ``POST /api/links``), which dies with the token it
was made for.
Missing or unknown token: 401; a known token whose role is too low: 403. With
``public_read`` reads need no token, but a token that is presented must still be valid.
"""

from __future__ import annotations

import base64
import contextlib
import enum
import hashlib
import hmac
import json
import logging
import secrets
import threading
import time
from collections.abc import Callable, Iterable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

from sqlalchemy.exc import SQLAlchemyError
from sqlalchemy.orm import Session, sessionmaker

from bench.inputs import InputError, check_text
from db.models import ApiToken
from db.repo.tokens import lookup_token, touch_token

log = logging.getLogger(__name__)
TOUCH_INTERVAL_S = 60.0
"""A database token's ``last_used_at`` is written at most this often (s)."""
LINK_TTL_S = 300.0
"""Lifetime of a signed link (s)."""
MAX_SECRET_CHARS = 200
"""Longest token secret looked up (a longer one is unknown without hashing it)."""


class Role(enum.IntEnum):
    """Ordered roles: a higher one may do everything a lower one may."""

    ANONYMOUS = 0
    VIEWER = 1
    OPERATOR = 2
    ADMIN = 3

    @property
    def label(self) -> str:
        """``viewer``, ``operator``, ``admin`` or ``anonymous``."""
        return self.name.lower()


class AuthError(Exception):
    """A request cannot be served for this token.

    :param status_code: 401 (no or unknown token) or 403 (role too low).
    """

    def __init__(self, status_code: int, message: str) -> None:
        super().__init__(message)
        self.status_code = status_code


@dataclass(frozen=True)
class Principal:
    """Who a request acts for: a role and, for a database token, its id (``None``: a configured
    token, or anonymous reading), and the operator's name stored with the token (``""``: none)."""

    role: Role
    token_id: int | None = None
    operator: str = ""

    @property
    def actor(self) -> str:
        """The name its actions are stored under: the operator's, else which token acted."""
        if self.operator:
            return self.operator
        if self.token_id is not None:
            return f"API token {self.token_id} (no operator name)"
        return f"{self.role.label} token of CALBENCH_TOKENS (no operator name)"


def _digest(secret: str) -> str:
    return hashlib.sha256(secret.encode("utf-8")).hexdigest()


def parse_token_names(entries: Iterable[str]) -> dict[str, str]:
    """``["operator:SECRET:Ada Lovelace", ...]`` -> ``{sha256(SECRET): "Ada Lovelace"}`` (entries
    without a name are left out; :func:`parse_tokens` checks the entries)."""
    names: dict[str, str] = {}
    for entry in entries:
        _, _, rest = entry.partition(":")
        secret, _, name = rest.partition(":")
        if name.strip():
            names[_digest(secret.strip())] = name.strip()
    return names


def parse_tokens(entries: Iterable[str]) -> dict[str, Role]:
    """``["operator:SECRET[:NAME]", ...]`` -> ``{sha256(SECRET): Role}`` (the names:
    :func:`parse_token_names`).

    :raises ValueError: an entry without ``role:``, an unknown role, a secret shorter than
        8 characters, a name that is not plain text of at most 100 characters, or one secret
        given two roles (the message names the entry by index).
    """
    table: dict[str, Role] = {}
    for i, entry in enumerate(entries):
        role_text, sep, rest = entry.partition(":")
        secret, _, name = rest.partition(":")
        where = f"CALBENCH_TOKENS entry {i + 1}"
        if not sep:
            raise ValueError(f"{where}: expected role:SECRET (e.g. operator:abc123...), got no ':'")
        role_name = role_text.strip().lower()
        if role_name not in ("viewer", "operator", "admin"):
            raise ValueError(f"{where}: role {role_text!r} is not viewer, operator or admin")
        secret = secret.strip()
        try:
            check_text(name.strip(), max_chars=100)
        except InputError as exc:
            raise ValueError(f"{where}: operator name: {exc}") from None
        if len(secret) < 8:
            raise ValueError(f"{where}: the {role_name} secret is shorter than 8 characters")
        digest = _digest(secret)
        if digest in table and table[digest] is not Role[role_name.upper()]:
            raise ValueError(f"{where}: the same secret is already given another role")
        table[digest] = Role[role_name.upper()]
    return table


def new_secret() -> str:
    """A fresh random token secret (URL-safe, 256 bits)."""
    return secrets.token_urlsafe(32)


class Authenticator:
    """Resolves a presented secret to a role.

    Database tokens are looked up in a read-only session (a request never waits for the
    write lock to authenticate); their ``last_used_at`` is written by one background thread,
    at most once per :data:`TOUCH_INTERVAL_S` per token.

    :param env_tokens: ``{sha256: Role}`` from :func:`parse_tokens`.
    :param env_names: ``{sha256: operator name}`` from :func:`parse_token_names`.
    :param sessions: writing session factory (``last_used_at``), or ``None`` for no database.
    :param read_sessions: read-only session factory for the look-up (default: ``sessions``).
    :param public_read: anonymous requests may read.
    :param link_key: the deployment's key for signed links (:class:`LinkSigner`); ``None``: one drawn here.
    """

    def __init__(
        self,
        env_tokens: dict[str, Role],
        sessions: sessionmaker[Session] | None = None,
        read_sessions: sessionmaker[Session] | None = None,
        *,
        public_read: bool = False,
        link_key: bytes | None = None,
        env_names: dict[str, str] | None = None,
    ) -> None:
        self._env = dict(env_tokens)
        self._names = dict(env_names or {})
        self._sessions = sessions
        self._read_sessions = read_sessions or sessions
        self.public_read = public_read
        self._touched: dict[int, float] = {}
        self._touch_lock = threading.Lock()
        self._toucher = ThreadPoolExecutor(max_workers=1, thread_name_prefix="token-last-used")
        self.links = LinkSigner(link_key)

    def add(self, secret: str, role: Role, operator: str = "") -> None:
        """Accept one more secret (e.g. the admin token generated at start), naming ``operator``."""
        self._env[_digest(secret)] = role
        if operator:
            self._names[_digest(secret)] = operator

    def is_env_secret(self, secret: str) -> bool:
        """``secret`` is one of the configured (not database) tokens."""
        return _digest(secret) in self._env

    def role_of(self, secret: str) -> Role | None:
        """The role of ``secret``, or ``None`` when no live token matches."""
        who = self.identify(secret)
        return who.role if who is not None else None

    def identify(self, secret: str) -> Principal | None:
        """The principal of ``secret``, or ``None`` when no live token matches."""
        if len(secret) > MAX_SECRET_CHARS or "\x00" in secret:
            return None
        digest = _digest(secret)
        role = self._env.get(digest)
        if role is not None or self._read_sessions is None:
            return Principal(role, None, self._names.get(digest, "")) if role is not None else None
        with self._read_sessions.begin() as s:
            token = lookup_token(s, secret)
            if token is None:
                return None
            token_id, role, operator = token.id, Role[token.role.name], token.operator
        self._schedule_touch(token_id)
        return Principal(role, token_id, operator)

    def is_live(self, who: Principal) -> bool:
        """``who`` may still act: a configured token or anonymous always, a database token
        while it is not revoked."""
        if who.token_id is None or self._read_sessions is None:
            return True
        with self._read_sessions.begin() as s:
            token = s.get(ApiToken, who.token_id)
            return token is not None and token.revoked_at is None

    def _schedule_touch(self, token_id: int) -> None:
        now = time.monotonic()
        with self._touch_lock:
            last = self._touched.get(token_id)
            if last is not None and now - last < TOUCH_INTERVAL_S:
                return
            self._touched[token_id] = now
        with contextlib.suppress(RuntimeError):  # closed: the service is stopping
            self._toucher.submit(self._touch, token_id)

    def _touch(self, token_id: int) -> None:
        if self._sessions is None:
            return
        try:
            with self._sessions.begin() as s:
                touch_token(s, token_id)
        except SQLAlchemyError:
            log.warning("could not record the use of API token %d", token_id, exc_info=True)

    def close(self) -> None:
        """Finish pending ``last_used_at`` writes and stop the background thread."""
        self._toucher.shutdown(wait=True)

    def require(self, secret: str | None, minimum: Role) -> Role:
        """The role of ``secret`` if it is at least ``minimum``.

        :raises AuthError: 401 for a missing/unknown token, 403 for a role too low.
        """
        return self.require_principal(secret, minimum).role

    def require_principal(self, secret: str | None, minimum: Role) -> Principal:
        """The principal of ``secret`` if its role is at least ``minimum``.

        :raises AuthError: 401 for a missing/unknown token, 403 for a role too low.
        """
        if not secret:
            if minimum <= Role.VIEWER and self.public_read:
                return Principal(Role.ANONYMOUS)
            raise AuthError(401, f"{minimum.label} token required (Authorization: Bearer TOKEN)")
        who = self.identify(secret)
        if who is None:
            raise AuthError(401, "unknown or revoked token")
        if who.role < minimum:
            raise AuthError(403, f"this needs the {minimum.label} role; the token is {who.role.label}")
        return who


def _b64(data: bytes) -> str:
    return base64.urlsafe_b64encode(data).rstrip(b"=").decode("ascii")


def _unb64(text: str) -> bytes:
    return base64.urlsafe_b64decode(text + "=" * (-len(text) % 4))


class LinkSigner:
    """Short-lived signed links: ``?link=PAYLOAD.MAC`` for one path, one principal, until a time.

    PAYLOAD is base64url JSON ``{"p": path, "e": expiry (Unix s), "r": role, "t": token id}``;
    MAC is its HMAC-SHA256 under the deployment's key (``CALBENCH_LINK_KEY``, or the one
    ``calbench serve`` draws and hands to all its workers), so a link opens on any API process.

    :param key: the HMAC key (default: 32 random bytes, links then open only on this process).
    :param clock: Unix time (s), for tests.
    """

    def __init__(self, key: bytes | None = None, clock: Callable[[], float] = time.time) -> None:
        self._key = key or secrets.token_bytes(32)
        self._clock = clock

    def _mac(self, payload: str) -> str:
        return _b64(hmac.new(self._key, payload.encode("utf-8", "replace"), hashlib.sha256).digest()[:20])

    def sign(self, path: str, who: Principal, ttl_s: float = LINK_TTL_S) -> tuple[str, float]:
        """The ``link`` query value for ``path`` and its expiry (Unix s)."""
        expires = round(self._clock() + ttl_s)
        body = {"p": path, "e": expires, "r": int(who.role), "t": who.token_id}
        payload = _b64(json.dumps(body, separators=(",", ":")).encode("utf-8"))
        return f"{payload}.{self._mac(payload)}", float(expires)

    def verify(self, link: str, path: str) -> Principal:
        """The principal a link was made for, if it is genuine, for ``path`` and not expired.

        :raises AuthError: 401 naming what is wrong with the link.
        """
        payload, _, mac = link.partition(".")
        if (
            not mac
            or len(link) > 2000
            or not hmac.compare_digest(self._mac(payload).encode(), mac.encode("utf-8", "replace"))
        ):
            raise AuthError(401, "link not signed by this service (ask for a new one: POST /api/links)")
        try:
            body = json.loads(_unb64(payload))
            link_path, expires, role, token_id = body["p"], float(body["e"]), Role(body["r"]), body["t"]
        except (ValueError, KeyError, TypeError):
            raise AuthError(401, "malformed link") from None
        if link_path != path:
            raise AuthError(401, "the link is for another resource")
        if self._clock() > expires:
            raise AuthError(401, "the link has expired (ask for a new one: POST /api/links)")
        return Principal(role, token_id if isinstance(token_id, int) else None)

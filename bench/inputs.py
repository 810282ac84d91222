"""The input layer: numbers, sizes and text as calbench accepts them from outside.

One set of rules for every door input comes in by: the recording reader (CSV fields),
the sidecar (JSON) and the service's request schemas. Each check raises
:class:`InputError` (a ``ValueError``) whose message says what is wrong and what was
expected; the caller adds where (file, line, key, field).

Numbers
    ASCII decimal only: ``[+-]digits[.digits][(e|E)[+-]digits]`` (``.5`` and ``5.`` too),
    at most :data:`MAX_NUMBER_CHARS` characters. Python's ``float()`` also reads ``1_0``,
    ``١٢`` (Arabic-Indic digits), ``１`` (full-width) and surrounding Unicode spaces; none of
    those is a number in a recording, so they are refused here rather than read as 10, 12, 1.
    Non-finite values (``nan``, ``inf``, or a literal that overflows, ``1e999``) are refused.
Sizes
    JSON documents: at most :data:`MAX_JSON_BYTES`, nested at most :data:`MAX_JSON_DEPTH`
    deep, integers of at most :data:`MAX_INT_DIGITS` digits, no duplicate keys. CSV fields:
    at most :data:`MAX_FIELD_CHARS` characters; the header line at most
    :data:`MAX_HEADER_CHARS`.
Text
    Stored text (serials, names, labels, addresses) contains no NUL or other C0/C1 control
    character except tab and newline where a field allows several lines, and no Unicode
    bidirectional control (U+202A–U+202E, U+2066–U+2069, U+200E, U+200F, U+061C): those
    reorder what a certificate shows (an address printed reversed) without being visible.
    JSON text decodes to no lone UTF-16 surrogate (``"\\ud800"`` unpaired): such a string has
    no UTF-8 form, so it could be neither stored nor sent back.
"""

from __future__ import annotations

import json
import math
import re
from typing import Any

MAX_NUMBER_CHARS = 100
"""Longest numeric CSV field or JSON number (characters): 17 significant digits need far fewer."""
MAX_INT_DIGITS = 19
"""Longest JSON integer (digits): a signed 64-bit integer has at most 19."""
MAX_INT = 2**63 - 1
"""Largest integer an identifier (a database key) may be: SQLite's and PostgreSQL's BIGINT."""
MAX_JSON_DEPTH = 32
"""Deepest nesting of objects and arrays in a JSON document (a sidecar needs 4)."""
MAX_JSON_BYTES = 16 * 1024 * 1024
"""Largest sidecar (bytes): about 200 000 segments."""
MAX_FIELD_CHARS = 4096
"""Longest CSV field (characters)."""
MAX_HEADER_CHARS = 65536
"""Longest CSV header line (characters)."""
MAX_TEXT_CHARS = 1000
"""Longest free-text value in a sidecar (characters)."""

_DECIMAL = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
BIDI_CONTROLS = "\u202a\u202b\u202c\u202d\u202e\u2066\u2067\u2068\u2069\u200e\u200f\u061c"
"""Unicode bidirectional controls: embeddings, overrides, isolates, marks."""
_BIDI = frozenset(BIDI_CONTROLS)
_UNPRINTABLE = re.compile(f"[{BIDI_CONTROLS}\\x00-\\x08\\x0b-\\x1f\\x7f-\\x9f]")
_CONTROL = re.compile(r"[\x00-\x08\x0b-\x1f\x7f-\x9f]")
_SURROGATE = re.compile("[\ud800-\udfff]")
_SURROGATE_ESCAPE = re.compile(r"\\u[dD][89a-fA-F][0-9a-fA-F]{2}")
_JSON_NESTING = re.compile(r'"(?:[^"\\]|\\.)*"|[\[\]{}]', re.DOTALL)


class InputError(ValueError):
    """A value from outside that breaks one of the input rules; the message says which."""


def parse_decimal(text: str) -> float:
    """A finite float from ASCII decimal text (surrounding ASCII spaces allowed).

    :raises InputError: not ASCII decimal, longer than :data:`MAX_NUMBER_CHARS`, or not finite.
    """
    s = text.strip(" \t")
    if len(s) > MAX_NUMBER_CHARS:
        raise InputError(f"number of {len(s)} characters; expected at most {MAX_NUMBER_CHARS}")
    if not _DECIMAL.fullmatch(s):
        if s.lower().lstrip("+-") in ("nan", "inf", "infinity"):
            raise InputError(f"non-finite value {s!r}; expected a finite number")
        raise InputError(f"not a number: {_show(s)}; expected ASCII decimal digits, '.', 'e'")
    x = float(s)
    if not math.isfinite(x):
        raise InputError(f"{s!r} overflows a double; expected a finite number")
    return x


def check_finite(value: float, what: str = "value") -> float:
    """``value`` if finite, else :class:`InputError`."""
    if not math.isfinite(value):
        raise InputError(f"{what} {value!r} is not finite; expected a finite number")
    return value


def check_text(value: str, *, max_chars: int = MAX_TEXT_CHARS, multiline: bool = False) -> str:
    """``value`` if it is acceptable stored text.

    :param max_chars: longest allowed length.
    :param multiline: newline and tab allowed (an address); else no control character at all.
    :raises InputError: too long, a NUL or control character, or a bidi control, naming its position.
    """
    if len(value) > max_chars:
        raise InputError(f"text of {len(value)} characters; expected at most {max_chars}")
    for i, ch in enumerate(value):
        if ch in _BIDI:
            raise InputError(
                f"bidirectional control U+{ord(ch):04X} at character {i + 1}; "
                "it would reorder the printed text"
            )
        allowed = multiline and ch in "\t\n\r"
        if (ch in "\t\n" or _CONTROL.match(ch)) and not allowed:
            raise InputError(f"control character U+{ord(ch):04X} at character {i + 1}; expected plain text")
    return value


def visible_text(value: str) -> str:
    """``value`` with every bidi control and C0/C1 control character (tab and newline kept) shown
    as ``?``: for output (a PDF) of text stored before these rules, nothing hidden, nothing reordered."""
    return _UNPRINTABLE.sub("?", value)


def check_identifier_text(value: str, *, max_chars: int = 64) -> str:
    """A serial number or name: non-empty, no surrounding spaces, plain text (see :func:`check_text`)."""
    if not value.strip():
        raise InputError("empty; expected a non-empty name (e.g. a serial number)")
    if value != value.strip():
        raise InputError(f"{value!r} has leading or trailing spaces")
    return check_text(value, max_chars=max_chars)


def _show(s: str, n: int = 40) -> str:
    return repr(s if len(s) <= n else s[:n] + "…")


def _line_col(text: str, pos: int) -> str:
    line = text.count("\n", 0, pos) + 1
    return f"line {line} column {pos - (text.rfind(chr(10), 0, pos) + 1) + 1}"


def check_json_nesting(text: str, max_depth: int = MAX_JSON_DEPTH) -> None:
    """Refuse JSON text nested deeper than ``max_depth`` before a parser recurses into it.

    :raises InputError: naming the line and column where the limit is passed.
    """
    depth = 0
    for m in _JSON_NESTING.finditer(text):
        tok = m.group()
        if tok in "[{":
            depth += 1
            if depth > max_depth:
                raise InputError(
                    f"nested deeper than {max_depth} levels at {_line_col(text, m.start())}; "
                    "expected a flat document"
                )
        elif tok in "]}":
            depth -= 1


def _parse_int(s: str) -> int:
    if len(s.lstrip("-")) > MAX_INT_DIGITS:
        raise InputError(f"integer of {len(s.lstrip('-'))} digits; expected at most {MAX_INT_DIGITS}")
    return int(s)


def _parse_float(s: str) -> float:
    if len(s) > MAX_NUMBER_CHARS:
        raise InputError(f"number of {len(s)} characters; expected at most {MAX_NUMBER_CHARS}")
    x = float(s)
    if not math.isfinite(x):
        raise InputError(f"{s} overflows a double; expected a finite number")
    return x


def _parse_constant(s: str) -> float:
    raise InputError(f"{s} is not JSON; expected a finite number")


def _no_duplicates(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for k, v in pairs:
        if k in out:
            raise InputError(f"duplicate key {_show(k)}; each key may appear once")
        out[k] = v
    return out


def _lone_surrogate(value: Any, where: str = "") -> str | None:
    """Where in a decoded JSON value a string (key or value) holds a lone surrogate, or ``None``.

    ``json`` joins an escaped pair (``\\ud83d\\ude00``) into one code point, so every surrogate
    left in a decoded string is unpaired."""
    if isinstance(value, str):
        m = _SURROGATE.search(value)
        return f"{where or 'the document'} character {m.start() + 1}" if m else None
    if isinstance(value, dict):
        for k, v in value.items():
            at = f"{where}.{k}" if where else str(k)
            if _SURROGATE.search(k):
                return f"a key in {where or 'the document'}"
            found = _lone_surrogate(v, at)
            if found:
                return found
    elif isinstance(value, list):
        for i, v in enumerate(value):
            found = _lone_surrogate(v, f"{where}[{i}]")
            if found:
                return found
    return None


def check_no_surrogates(value: Any) -> Any:
    """``value`` (decoded JSON) if no string in it holds a lone UTF-16 surrogate.

    :raises InputError: naming the key path and character of the first one.
    """
    found = _lone_surrogate(value)
    if found is not None:
        raise InputError(f"lone UTF-16 surrogate at {_ascii(found)}; expected text that has a UTF-8 form")
    return value


def _ascii(text: str) -> str:
    return text.encode("ascii", "backslashreplace").decode("ascii")


def loads_json(text: str, *, max_bytes: int = MAX_JSON_BYTES, finite: bool = True) -> Any:
    """Decode JSON text under the size rules: length, nesting, integer digits, finite numbers,
    no duplicate keys, no ``NaN``/``Infinity``, no lone UTF-16 surrogate in a string.

    :param finite: refuse ``NaN``, ``Infinity`` and overflowing literals here; ``False`` leaves
        them to a later validator that names the field (the service's request models).

    :raises InputError: a size rule broken (the message names it).
    :raises json.JSONDecodeError: not JSON at all.
    """
    if len(text) > max_bytes:
        raise InputError(f"document of {len(text)} characters; expected at most {max_bytes}")
    check_json_nesting(text)
    if not finite:
        value = json.loads(text, parse_int=_parse_int, object_pairs_hook=_no_duplicates)
    else:
        value = json.loads(
            text,
            parse_int=_parse_int,
            parse_float=_parse_float,
            parse_constant=_parse_constant,
            object_pairs_hook=_no_duplicates,
        )
    if _SURROGATE_ESCAPE.search(text) or _SURROGATE.search(text):
        check_no_surrogates(value)
    return value

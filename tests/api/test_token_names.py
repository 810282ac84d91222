"""Tokens name the person they stand for: ``CALBENCH_TOKENS`` entries ``role:SECRET[:NAME]``."""

from __future__ import annotations

import pytest

from api.auth import Authenticator, Role, parse_token_names, parse_tokens


def test_token_names_from_the_environment() -> None:
    entries = ["operator:secret-one-1:Ada Lovelace", "viewer:secret-two-2", "admin:secret-three:  Lab  "]
    roles = parse_tokens(entries)
    assert sorted(r.label for r in roles.values()) == ["admin", "operator", "viewer"]
    auth = Authenticator(roles, env_names=parse_token_names(entries))
    ada, viewer, admin = (auth.identify(s) for s in ("secret-one-1", "secret-two-2", "secret-three"))
    assert ada is not None and (ada.role, ada.actor) == (Role.OPERATOR, "Ada Lovelace")
    assert admin is not None and admin.actor == "Lab"
    assert viewer is not None and viewer.operator == ""
    assert viewer.actor == "viewer token of CALBENCH_TOKENS (no operator name)"


def test_a_name_must_be_plain_text() -> None:
    with pytest.raises(ValueError, match="entry 1: operator name"):
        parse_tokens(["operator:secret-one-1:Ada\x00"])
    with pytest.raises(ValueError, match="entry 1: operator name"):
        parse_tokens(["operator:secret-one-1:" + "x" * 101])


def test_an_entry_without_a_name_is_as_before() -> None:
    assert parse_tokens(["operator:secret-one-1"]) == parse_tokens(["operator:secret-one-1:Ada"])
    assert parse_token_names(["operator:secret-one-1"]) == {}

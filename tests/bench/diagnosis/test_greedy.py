"""The selection core's rules on toy models whose answer is known by construction."""

from __future__ import annotations

from bench.diagnosis.greedy import Path, Trial, admits, backward, best, extend, forward, resume, step_alpha


def test_admission_needs_the_gate_and_a_lower_bic() -> None:
    assert admits(Trial("a", 12.0, 10.0, -1.0))
    assert not admits(Trial("a", 9.0, 10.0, -5.0))  # below its gate
    assert not admits(Trial("a", 12.0, 10.0, 0.5))  # BIC not lowered


def test_best_is_the_admissible_of_lowest_bic_first_of_equals() -> None:
    trials = [
        Trial("gate fails", 1.0, 10.0, -50.0),
        Trial("b", 20.0, 10.0, -3.0),
        Trial("c", 30.0, 10.0, -7.0),
        Trial("d", 31.0, 10.0, -7.0),
    ]
    won = best(trials)
    assert won is not None and won.item == "c"
    assert best([Trial("x", 1.0, 2.0, -1.0)]) is None


def test_step_alpha_shares_the_budget() -> None:
    assert step_alpha(0.01, 4) == 0.0025
    assert step_alpha(0.01, 0) == 0.01


def test_forward_takes_the_first_group_with_a_candidate() -> None:
    # group 1 admits while the state is below 2, group 2 always admits, max 5 steps
    calls: list[str] = []

    def first(s: tuple[str, ...]) -> tuple[str, ...] | None:
        calls.append("first")
        return (*s, "first") if len(s) < 2 else None

    def second(s: tuple[str, ...]) -> tuple[str, ...] | None:
        calls.append("second")
        return (*s, "second")

    start: tuple[str, ...] = ()
    state, n = forward(start, [first, second], 5)
    assert state == ("first", "first", "second", "second", "second")
    assert n == 5
    assert calls.count("second") == 3  # asked only once the first group had nothing


def test_forward_stops_when_no_group_admits() -> None:
    state, n = forward(3, [lambda s: s - 1 if s > 0 else None], 10)
    assert (state, n) == (0, 3)


def test_backward_removes_the_worst_until_all_pass() -> None:
    # each effect's score; one below 1 fails, the lowest goes first
    def worst(s: dict[str, float]) -> tuple[str, dict[str, float]] | None:
        failing = {k: v for k, v in s.items() if v < 1.0}
        if not failing:
            return None
        k = min(failing, key=failing.__getitem__)
        return k, {j: v for j, v in s.items() if j != k}

    state, removed = backward({"a": 3.0, "b": 0.2, "c": 0.5}, worst)
    assert removed == ["b", "c"]
    assert state == {"a": 3.0}


def test_resume_goes_back_to_the_step_before_and_keeps_what_came_before() -> None:
    # the state is the tuple of admitted items; the group admits the smallest item of the pool
    # not in the state and not excluded (excluded items are the last element, a frozenset)
    asked: list[tuple[str, ...]] = []

    def admit(s: tuple[frozenset[str], tuple[str, ...]], notes: dict[str, str]):  # type: ignore[no-untyped-def]
        out, items = s
        asked.append(items)
        left = sorted(set("abcd") - set(items) - out)
        notes[f"after {''.join(items)}"] = "asked"
        return (out, (*items, left[0])) if left else None

    start: tuple[frozenset[str], tuple[str, ...]] = (frozenset(), ())
    path = extend(Path.start(start), [admit], 3)
    assert path.last[1] == ("a", "b", "c") and path.steps == 3
    assert list(path.noted) == ["after ", "after a", "after ab"]
    asked.clear()
    again = resume(path, [admit], 3, lambda s: "b" in s[1], lambda s: (s[0] | {"b"}, s[1]))
    # back to the state before b entered, b excluded, then forward: a, c, d
    assert again.last[1] == ("a", "c", "d")
    assert again.states[0] is path.states[0]
    assert asked == [("a",), ("a", "c")]  # nothing before b's admission asked again
    assert list(again.noted) == ["after ", "after a", "after ac"]
    # nothing holds: the exclusion applies at the end and the path goes on
    more = resume(again, [admit], 4, lambda s: "z" in s[1], lambda s: s)
    assert more.last[1] == ("a", "c", "d") and more.steps == 3

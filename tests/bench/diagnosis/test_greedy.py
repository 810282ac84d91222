"""The selection core's rules on toy models whose answer is known by construction."""

from __future__ import annotations

from bench.diagnosis.greedy import Trial, admits, backward, best, forward, step_alpha


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

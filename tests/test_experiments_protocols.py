"""Protocol design: Williams-square balance, seeding, validation of protocol files."""

from __future__ import annotations

import itertools

import pytest

from tactilize.experiments.protocols import (
    ProtocolError,
    balanced_latin_square,
    builtin_names,
    load_protocol,
    protocol_from_toml,
    williams_row,
)


def _adjacent_pairs(rows):
    counts = {}
    for row in rows:
        for a, b in zip(row, row[1:]):
            counts[(a, b)] = counts.get((a, b), 0) + 1
    return counts


@pytest.mark.parametrize("n", [2, 3, 4, 5, 8, 10])
def test_williams_square_is_latin_and_carry_over_balanced(n):
    rows = balanced_latin_square(n)
    height = n if n % 2 == 0 else 2 * n
    assert len(rows) == height
    for row in rows:
        assert sorted(row) == list(range(n))
    # Every condition at every position equally often.
    for pos in range(n):
        column = [row[pos] for row in rows]
        assert all(column.count(c) == height // n for c in range(n))
    # Every ordered pair of distinct conditions adjacent equally often (first-order carry-over).
    pairs = _adjacent_pairs(rows)
    expected = 1 if n % 2 == 0 else 2
    assert set(pairs) == {(a, b) for a, b in itertools.permutations(range(n), 2)}
    assert set(pairs.values()) == {expected}


def test_rows_repeat_with_the_square_height():
    assert williams_row(4, 0) == williams_row(4, 4)
    assert williams_row(5, 1) == williams_row(5, 11)
    assert williams_row(5, 5) == williams_row(5, 0)[::-1]


def test_builtin_protocols_mirror_the_paper():
    assert builtin_names() == ["alpha-law", "assessment", "g-law", "h-law", "perceptual-law"]
    g = load_protocol("g-law")
    assert len(g.conditions) == 10 and len(g.images) == 3 and g.participants_planned == 8
    # The paper's best g is "I": log, k2 = 40.
    assert g.profile("I").frequency.k2 == 40.0 and g.profile("I").frequency.kind == "log"
    assert g.profile("A").frequency.kind == "linear"
    h = load_protocol("h-law")
    assert h.profile("D").width.k3 == 40.0
    a = load_protocol("alpha-law")
    assert a.profile("B").speed.slope_per_mm_s == 0.05
    s = load_protocol("assessment")
    assert len(s.images) == 6 and len(s.questions) == 4 and s.participants_planned == 10
    assert [im.spatial_frequency_per_m for im in s.images] == [799, 563, 287, 265, 443, 4217]
    for p in (g, h, a, s):
        assert all(q.scale_min == 1 and q.scale_max == 7 for q in p.questions)


@pytest.mark.parametrize("name", ["g-law", "alpha-law", "h-law"])
def test_participants_fill_a_balanced_square(name):
    p = load_protocol(name)
    n = len(p.conditions)
    height = n if n % 2 == 0 else 2 * n
    orders = [p.condition_order(k) for k in range(1, height + 1)]
    ids = [c.id for c in p.conditions]
    for pos in range(n):
        column = [o[pos] for o in orders]
        assert sorted(column) == sorted(ids * (height // n))
    pairs = _adjacent_pairs(orders)
    assert len(pairs) == n * (n - 1) and len(set(pairs.values())) == 1
    # The next participants start the square again: the order is a function of the number.
    assert p.condition_order(height + 1) == orders[0]


def test_order_is_seeded_and_recomputable():
    p = load_protocol("alpha-law")
    assert p.plan(3) == p.plan(3)
    changed = protocol_from_toml(p.text.replace("seed = 1003", "seed = 1004"))
    assert changed.sha256 != p.sha256
    assert [changed.condition_order(k) for k in range(1, 5)] != [p.condition_order(k) for k in range(1, 5)]


def test_condition_image_trials_and_repetitions():
    p = load_protocol("alpha-law")
    text = p.text.replace('trial_unit = "condition"', 'trial_unit = "condition_image"').replace(
        "repetitions = 1", "repetitions = 2")
    q = protocol_from_toml(text)
    plan = q.plan(1)
    assert len(plan) == 4 * 3 * 2
    assert all(len(t.image_ids) == 1 for t in plan)
    # Each condition x image x repetition exactly once.
    assert len({(t.condition_id, t.image_ids[0], t.repetition) for t in plan}) == len(plan)


@pytest.mark.parametrize(
    "mutate, fault",
    [
        (lambda t: t.replace('law = "sigmoid"', 'law = "quadratic"', 1), "quadratic"),
        (lambda t: t.replace("seed = 1003", "seed = -3"), "seed"),
        (lambda t: t.replace('id = "speed_match"', 'id = "speed match"'), "short id"),
        (lambda t: t + "\nbogus = 1\n", "unknown key"),
        (lambda t: t.replace("[order]", "[order"), "invalid TOML"),
        (lambda t: t.replace('id = "B"', 'id = "A"'), "unique"),
    ],
)
def test_bad_protocols_are_refused_with_a_reason(mutate, fault):
    text = load_protocol("alpha-law").text
    with pytest.raises(ProtocolError) as err:
        protocol_from_toml(mutate(text), source="bad.toml")
    assert fault in str(err.value)
    assert err.value.source == "bad.toml"


def test_unknown_protocol_name():
    with pytest.raises(ProtocolError, match="neither a built-in"):
        load_protocol("no-such-protocol")


def test_package_exports_resolve():
    import tactilize.experiments as E
    import tactilize.experiments.simulate  # noqa: F401  (the submodule must not shadow the function)

    for name in E.__all__:
        assert getattr(E, name) is not None
    assert callable(E.simulate_participants) and E.simulate_participants.__module__.endswith("simulate")

"""Key paths as error messages write them: parsed, read and set on problem data."""

import re

import pytest

from cpopt.io.keypath import KeyPathError, check_disjoint, get_value, parse_key_path, with_values
from cpopt.problem.keytypes import BOOLEAN, NUMBER, WORD, KeyType, key_type

DATA = {"arm": {"links": [{"mass": 1.0}, {"mass": 2.0}, {"mass": 3.0}]}, "motion": {"T": 1}}


def test_parse_names_and_indices():
    assert parse_key_path("arm.links[2].mass") == ("arm", "links", 2, "mass")
    assert parse_key_path("optimizer.limits.torque[0]") == ("optimizer", "limits", "torque", 0)


@pytest.mark.parametrize("bad", ["", "[0].a", "arm..links", "arm.links[x]", "a b", "arm."])
def test_parse_refuses_malformed(bad):
    with pytest.raises(KeyPathError):
        parse_key_path(bad)


def test_get_and_set_leave_the_input_alone():
    out = with_values(DATA, {"arm.links[2].mass": 4.5, "motion.duration": 2.0})
    assert get_value(out, "arm.links[2].mass") == 4.5
    assert out["motion"] == {"T": 1, "duration": 2.0}
    assert DATA["arm"]["links"][2]["mass"] == 3.0 and "duration" not in DATA["motion"]


def test_missing_mappings_are_created():
    out = with_values(DATA, {"optimizer.limits.torque_headroom": 0.1})
    assert out["optimizer"] == {"limits": {"torque_headroom": 0.1}}


def test_errors_name_where_the_path_fails():
    with pytest.raises(KeyPathError, match=r"arm.links has 3 item\(s\); no item \[5\]"):
        with_values(DATA, {"arm.links[5].mass": 1.0})
    with pytest.raises(KeyPathError, match=r"arm.links\[0\].mass is not a mapping"):
        with_values(DATA, {"arm.links[0].mass.x": 1.0})
    with pytest.raises(KeyPathError, match="no key 'goal' at motion"):
        get_value(DATA, "motion.goal.x")


def test_two_values_for_one_key_are_refused_naming_both():
    check_disjoint(["motion.duration", "motion.goal.x", "arm.links[2].mass"])
    for paths, words in [
        (["motion.duration", " motion.duration"], "also given as  motion.duration (the same key)"),
        (["motion", "motion.duration"], "also given as motion.duration (one inside the other)"),
        (["arm.links[2].mass", "arm.links[2]"], "also given as arm.links[2] (one inside"),
    ]:
        with pytest.raises(KeyPathError, match=re.escape(words)):
            check_disjoint(paths)
    with pytest.raises(KeyPathError, match="one inside the other"):
        with_values(DATA, {"motion": {"duration": 1.0}, "motion.duration": 2.0})


def test_a_keys_type_is_read_from_the_schema():
    assert key_type("motion.duration") == KeyType(frozenset({NUMBER}))
    assert key_type("arm.links[2].mass") == KeyType(frozenset({NUMBER}))
    assert key_type("planner").words == ("closed_form", "optimize", "collocation")
    assert key_type("optimizer.smooth_torque") == KeyType(frozenset({BOOLEAN}))
    assert key_type("arm.branch") == KeyType(frozenset({WORD}))  # any text
    switches = key_type("optimizer.gamma_switches")
    assert switches.kinds == {NUMBER, WORD} and switches.words == ("auto",)
    assert switches.describe() == "a finite number or one of auto"
    assert key_type("optimizer.objective.energy") == KeyType(frozenset({NUMBER}))
    for path in ("arm.links", "motion.duraton", "optimizer.free.start.xi", "arm.base[0].x"):
        assert key_type(path) is None, path

"""Study files: the examples parse and build; malformed files are refused with the key named."""

import dataclasses
import hashlib
import json

import pytest
from study_helpers import EXAMPLES

from mindgap.cli import main
from mindgap.study.config import StudyFileError, load_study, parse_study
from mindgap.study.items import build_items

MINIMAL = {"name": "s", "protocol": "rating", "domain": {"name": "coffee"}, "items": {"source": "coffee-demos"}}


@pytest.mark.parametrize("name", ["coffee-rating", "grid7-rating", "terrain-live"])
def test_examples_parse_and_build(name):
    study = load_study(EXAMPLES / f"{name}.yaml")
    items = build_items(study)
    if study.live:
        assert items == []
    else:
        assert len({it.id for it in items}) == len(items) > 0
        assert all(it.sanity for it in items if it.id in {s.item for s in study.sanity})


def test_coffee_example_is_the_dissertation_study():
    study = load_study(EXAMPLES / "coffee-rating.yaml")
    items = build_items(study)
    assert len(items) == 9 and [q.id for q in study.questionnaire] == ["q1", "q2"]
    assert study.conditions() == ("mobile", "humanoid")
    sanity = [it for it in items if it.sanity]
    assert [(it.id, it.sanity["rule"]) for it in sanity] == [("sanity-random", "lowest")]
    for it in items:  # n actions, n + 1 states (the last one is where the demonstration ends)
        assert len(it.data["states"]) == len(it.data["actions"]) + 1


@pytest.mark.parametrize(
    "change, message",
    [
        ({"protocol": "ranking"}, "protocol 'ranking' is not one of rating, preference, expectation"),
        ({"name": "Bad Name!"}, "name 'Bad Name!' must be lower-case"),
        ({"domain": {"name": "chess"}}, "domain.name must be one of"),
        ({"items": {"source": "random-pairs"}}, "items.source 'random-pairs' does not fit domain coffee"),
        ({"participants": "many"}, "participants must be an integer"),
        ({"min_seconds": -1}, "min_seconds must be at least 0"),
        (
            {"questionnaire": [{"id": "q1", "text": "?", "scale": [5, 1]}]},
            "questionnaire[0].scale must be two integers",
        ),
        ({"questionnaire": [{"text": "?"}]}, "questionnaire[0] needs an id and a text"),
        ({"sanity": [{"item": "x", "rule": "answer", "value": "a"}]}, "rule answer is for comparisons"),
        ({"rating": {"min": 5, "max": 1}}, "rating needs min < max"),
        ({"colour": "red"}, "unknown key(s) colour"),
        ({"protocol": "preference"}, "domain coffee shows demonstrations to rate"),
        ({"min_live_answers": 3}, "min_live_answers belongs to a live study"),
        ({"waiting": "Wait."}, "waiting belongs to a live study"),
    ],
)
def test_malformed_study_files_name_the_problem(change, message):
    with pytest.raises(StudyFileError, match=None) as e:
        parse_study({**MINIMAL, **change}, source="study.yaml")
    assert message in str(e.value) and str(e.value).startswith("study.yaml: ")


def test_a_missing_key_and_bad_yaml(tmp_path):
    with pytest.raises(StudyFileError, match="missing key 'items'"):
        parse_study({k: v for k, v in MINIMAL.items() if k != "items"})
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: [unclosed\n")
    with pytest.raises(StudyFileError, match="not valid YAML"):
        load_study(bad)
    with pytest.raises(StudyFileError, match="does not exist"):
        load_study(tmp_path / "none.yaml")


def test_a_sanity_rule_must_name_an_item():
    study = parse_study({**MINIMAL, "sanity": [{"item": "no-such-demo", "rule": "lowest"}]})
    with pytest.raises(StudyFileError, match="sanity item 'no-such-demo' is not one of the study's items"):
        build_items(study)


def test_cli_check_and_examples(tmp_path, capsys):
    assert main(["study", "examples"]) == 0
    listed = capsys.readouterr().out
    assert all(
        name in listed for name in ("coffee-rating", "terrain-preference", "terrain-expectation", "terrain-live")
    )
    assert main(["study", "examples", "coffee-rating", "--out", str(tmp_path / "c.yaml")]) == 0
    assert main(["study", "check", "--config", str(tmp_path / "c.yaml")]) == 0
    assert "9 items" in capsys.readouterr().out
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: x\nprotocol: rating\n")
    assert main(["study", "check", "--config", str(bad)]) == 2
    assert "missing key 'domain'" in capsys.readouterr().err
    assert main(["study", "examples", "nope"]) == 2


def test_serve_binds_this_machine_only_by_default():
    from mindgap.cli import _parser

    args = _parser().parse_args(["study", "serve", "--config", "x.yaml"])
    assert args.host == "127.0.0.1"


def test_the_live_keys_are_read_and_leave_older_studies_fingerprints_alone():
    live = {**MINIMAL, "protocol": "preference", "domain": {"name": "terrain", "world": "nav1"}}
    live["items"] = {"source": "live"}
    plain = parse_study(live)
    assert (plain.min_live_answers, plain.waiting) == (0, "")
    assert plain.waiting_text.startswith("The robot is still learning")
    keyed = parse_study({**live, "min_live_answers": 5, "waiting": "One moment."})
    assert (keyed.min_live_answers, keyed.waiting_text) == (5, "One moment.")
    assert keyed.fingerprint() != plain.fingerprint()
    # a store made before these keys existed hashed the study without them
    before = dataclasses.asdict(plain)
    for key in ("base_dir", "waiting", "min_live_answers"):
        before.pop(key)
    assert plain.fingerprint() == hashlib.sha256(json.dumps(before, sort_keys=True).encode()).hexdigest()[:16]
    with pytest.raises(StudyFileError, match="min_live_answers must be at least 0"):
        parse_study({**live, "min_live_answers": -1})

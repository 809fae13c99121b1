"""The store: WAL, schema versions and migrations, one study per store, answers recorded once."""

import sqlite3

import pytest
from study_helpers import EXAMPLES, study_file

from mindgap.study.config import load_study
from mindgap.study.items import build_items
from mindgap.study.store import SCHEMA_VERSION, Store, StoreError


@pytest.fixture
def study():
    return load_study(EXAMPLES / "coffee-rating.yaml")


def _bound(path, study):
    store = Store(path)
    store.bind_study(study, [it.as_dict() for it in build_items(study)])
    return store


def test_store_is_wal_and_at_the_current_version(tmp_path, study):
    store = _bound(tmp_path / "s.sqlite", study)
    assert store.conn().execute("PRAGMA journal_mode").fetchone()[0] == "wal"
    assert store.version() == SCHEMA_VERSION
    assert len(store.participants()) == study.participants
    tokens = [p["token"] for p in store.participants()]
    assert len(set(tokens)) == len(tokens) and min(len(t) for t in tokens) >= 24  # 18 random bytes


def test_an_old_store_is_migrated_without_losing_answers(tmp_path, study):
    old = Store(tmp_path / "s.sqlite", upto=1)
    assert old.version() == 1
    old.bind_study(study, [it.as_dict() for it in build_items(study)])
    assert old.record_answer(1, "sunny-umbrella", 7.0, None, "sub-00000001") == "stored"
    old.close()
    new = Store(tmp_path / "s.sqlite")
    assert new.version() == SCHEMA_VERSION
    assert [(a["item_id"], a["value"]) for a in new.answers()] == [("sunny-umbrella", 7.0)]
    assert new.live_counts() == {"open": 0, "answered": 0, "expired": 0}  # the table migration 2 added


def test_a_newer_store_is_refused(tmp_path):
    Store(tmp_path / "s.sqlite")
    con = sqlite3.connect(tmp_path / "s.sqlite")
    con.execute("UPDATE schema_version SET version = ?", (SCHEMA_VERSION + 1,))
    con.commit()
    con.close()
    with pytest.raises(StoreError, match="newer than this mindgap"):
        Store(tmp_path / "s.sqlite")


def test_a_store_belongs_to_one_study(tmp_path, study):
    _bound(tmp_path / "s.sqlite", study)
    other = load_study(study_file(tmp_path, "coffee-rating", min_seconds=1))
    with pytest.raises(StoreError, match="another study"):
        Store(tmp_path / "s.sqlite").bind_study(other, [])
    assert Store(tmp_path / "s.sqlite").bind_study(study, []) is False  # the same study reopens


def test_answers_are_recorded_exactly_once(tmp_path, study):
    store = _bound(tmp_path / "s.sqlite", study)
    assert store.record_answer(1, "sunny-umbrella", 7.0, None, "sub-00000001") == "stored"
    assert store.record_answer(1, "sunny-umbrella", 7.0, None, "sub-00000001") == "duplicate"
    assert store.record_answer(1, "sunny-umbrella", 2.0, None, "sub-00000002") == "answered"
    assert store.record_answer(2, "sunny-umbrella", 2.0, None, "sub-00000001") == "conflict"
    assert store.record_answer(2, "sunny-umbrella", 2.0, None, "sub-00000003") == "stored"
    assert sorted((a["participant"], a["value"]) for a in store.answers()) == [("p-001", 7.0), ("p-002", 2.0)]


def test_order_and_viewing_time_are_checked_in_the_answers_transaction(tmp_path, study):
    store = _bound(tmp_path / "s.sqlite", study)
    order = ["sunny-umbrella", "rainy-umbrella"]
    assert store.record_answer(1, "rainy-umbrella", 7.0, None, "sub-00000001", order=order) == "out-of-order"
    record = dict(order=order, min_seconds=60.0)
    assert store.record_answer(1, "sunny-umbrella", 7.0, None, "sub-00000002", **record) == "not-shown"
    store.first_view(1, "sunny-umbrella")
    assert store.record_answer(1, "sunny-umbrella", 7.0, None, "sub-00000003", **record) == "too-fast"
    assert store.answers() == []
    record["min_seconds"] = 0.0
    assert store.record_answer(1, "sunny-umbrella", 7.0, None, "sub-00000004", **record) == "stored"
    # the same form again once the item is no longer the current one: still its own outcome, not out of order
    assert store.record_answer(1, "sunny-umbrella", 7.0, None, "sub-00000004", **record) == "duplicate"
    assert store.record_answer(1, "sunny-umbrella", 7.0, None, "sub-00000005", **record) == "answered"


def test_live_queries_go_to_one_participant_and_can_be_withdrawn(tmp_path):
    study = load_study(EXAMPLES / "terrain-live.yaml")
    store = _bound(tmp_path / "s.sqlite", study)
    batch = store.post_live_batch("run", [{"a": {}, "b": {}}, {"a": {}, "b": {}}])
    q1, q2 = store.claim_live(1), store.claim_live(2)
    assert q1 != q2 and store.claim_live(1) == q1  # a participant keeps their query
    assert store.claim_live(3) is None  # both are taken
    assert store.record_answer(2, f"live-{q1}", 1.0, "a", "sub-00000010") == "not-yours"
    assert store.record_answer(1, f"live-{q1}", 1.0, "a", "sub-00000011") == "stored"
    store.close_batch(batch)
    assert store.record_answer(2, f"live-{q2}", 0.0, "b", "sub-00000012") == "closed"
    assert store.live_counts(batch) == {"open": 0, "answered": 1, "expired": 1}
    assert store.batch_answers(batch) == {0: "a"}

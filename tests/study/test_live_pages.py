"""What a participant of a live study meets: withdrawn questions, passed leases, finishing, waiting text."""

import hashlib
import hmac
import html
import re
import time

from fastapi.testclient import TestClient
from study_helpers import ADMIN, Participant, hidden, study_file

from mindgap.study.app import create_app
from mindgap.study.server import open_study

PAIR = {"a": {"obs": [[0.0, 0.0]]}, "b": {"obs": [[1.0, 1.0]]}}


def _live(tmp_path, example="terrain-live", lease=120.0, **changes):
    tmp_path.mkdir(parents=True, exist_ok=True)
    changes.setdefault("participants", 2)
    changes.setdefault("min_seconds", 0)
    study, store, renderer = open_study(study_file(tmp_path, example, **changes), tmp_path / "live.sqlite", ADMIN)
    return store, TestClient(create_app(study, store, renderer, live_lease=lease))


def _waiting(client, store, k=0) -> Participant:
    """Participant ``k`` past consent and instructions (terrain-live has no questionnaire)."""
    p = Participant(client, store.participants()[k]["token"], rate=lambda item: "a")
    p.step(), p.step()
    return p


def _terrain_pair() -> dict:
    """A pair of real nav1 segments (one whose pictures can be drawn)."""
    import jax
    import numpy as np

    from mindgap.envs.terrain import load_world
    from mindgap.study.items import random_segments, segment_dict

    s = {k: np.asarray(v) for k, v in random_segments(jax.random.key(0), load_world("nav1").params, 2, 4).items()}
    return {"a": segment_dict(s, 0), "b": segment_dict(s, 1)}


def _notice(page: str) -> str:
    m = re.search(r'<p class="notice" role="status">([^<]*)</p>', page)
    return html.unescape(m.group(1)) if m else ""


def _answer(p: Participant, page: str):
    form = {"csrf": hidden(page, "csrf"), "item_id": hidden(page, "item_id"), "choice": "a"}
    return p.post("answer", {**form, "submission_id": hidden(page, "submission_id")})


def test_a_withdrawn_question_redirects_to_the_next_page_with_a_notice(tmp_path):
    store, client = _live(tmp_path)
    p = _waiting(client, store)
    batch = store.post_live_batch("study:run", [PAIR])
    page = p.get()
    assert hidden(page, "item_id") == "live-1"
    store.close_batch(batch)  # the run stopped waiting while the page was open
    r = _answer(p, page)
    assert r.status_code == 303 and r.headers["x-answer"] == "closed"  # post/redirect/get, no 410 page
    assert r.headers["location"] == f"/p/{p.token}?notice=closed"
    shown = client.get(r.headers["location"])
    assert shown.status_code == 200 and "Waiting for the next question" in shown.text
    assert _notice(shown.text) == "That question was withdrawn before your answer arrived, so it was not recorded."
    assert client.get(r.headers["location"]).status_code == 200  # a reload shows the page again
    assert store.answers() == []


def test_a_question_whose_lease_passed_to_another_participant_is_still_answered_once(tmp_path):
    store, client = _live(tmp_path, lease=0.2)
    a, b = _waiting(client, store, 0), _waiting(client, store, 1)
    store.post_live_batch("study:run", [_terrain_pair()])
    page_a = a.get()
    time.sleep(0.3)  # a's lease runs out while the page is open; b arrives and is given the question
    page_b = b.get()
    assert hidden(page_a, "item_id") == hidden(page_b, "item_id") == "live-1"
    for part in "ab":  # a's page still shows its pictures
        assert client.get(f"/p/{a.token}/media/live-1/{part}").status_code == 200
    r = _answer(a, page_a)
    assert r.status_code == 303 and r.headers["x-answer"] == "stored"  # no "404 Unknown item 'live-1'"
    r = _answer(b, page_b)
    assert r.status_code == 303 and r.headers["x-answer"] == "taken"
    shown = client.get(r.headers["location"]).text
    assert _notice(shown) == "Someone else answered that question first, so your answer was not recorded."
    assert [(x["participant"], x["item_id"]) for x in store.answers()] == [("p-001", "live-1")]
    assert store.live_counts() == {"open": 0, "answered": 1, "expired": 0}


def test_a_live_query_never_shown_to_a_participant_stays_unknown_to_them(tmp_path):
    store, client = _live(tmp_path)
    a, b = _waiting(client, store, 0), _waiting(client, store, 1)
    store.post_live_batch("study:run", [PAIR])
    assert hidden(a.get(), "item_id") == "live-1"
    page_b = b.get()  # b waits: the one question is a's
    assert "Waiting for the next question" in page_b
    form = {"csrf": hidden(page_b, "csrf"), "item_id": "live-1", "submission_id": "made-up-0001", "choice": "b"}
    assert b.post("answer", form).status_code == 404
    assert client.get(f"/p/{b.token}/media/live-1/a").status_code == 404
    assert store.answers() == []


def test_the_completion_code_waits_for_the_minimum_number_of_live_answers(tmp_path):
    store, client = _live(tmp_path, min_live_answers=2)
    p = _waiting(client, store)
    page = p.get()
    assert 'id="finish"' not in page and "at least 2 of these questions" in page
    csrf = hmac.new(store.meta("secret").encode(), f"p:{p.token}".encode(), hashlib.sha256).hexdigest()
    r = p.post("finish", {"csrf": csrf})  # a finish form from before, or made by hand
    assert r.status_code == 303 and r.headers["location"] == f"/p/{p.token}?notice=more"
    assert _notice(client.get(r.headers["location"]).text) == "Please answer at least 2 questions before you finish."
    assert store.participants()[0]["completed_at"] is None
    store.post_live_batch("study:run", [PAIR, PAIR])
    p.step(), p.step()  # two live answers
    page = p.get()
    assert 'id="finish"' in page
    assert p.post("finish", {"csrf": hidden(page, "csrf")}).status_code == 303
    assert store.participants()[0]["completion_code"] in p.get()


def test_dashboard_counts_of_a_live_study_with_fixed_items_add_up(tmp_path):
    store, client = _live(tmp_path, "driving-training", participants=1, questionnaire=[])
    p = Participant(client, store.participants()[0]["token"], rate=lambda item: "a")
    for _ in range(4):  # consent, instructions, the bias question and the sanity item
        p.step()
    store.post_live_batch("study:run", [PAIR])
    p.step()  # one live answer
    admin = {"Authorization": f"Bearer {ADMIN}"}
    person = client.get("/admin/api/status", headers=admin).json()["people"][0]
    assert (person["answered"], person["total"], person["live_answered"]) == (3, 2, 1)
    row = re.search(r"<td>p-001</td>.*?</tr>", client.get("/admin", headers=admin).text, re.S).group(0)
    assert "2 / 2 fixed + 1 live" in row and "3 / 2" not in row


def test_the_waiting_text_fits_the_task(tmp_path):
    store, client = _live(tmp_path, "driving-training", participants=1, questionnaire=[])
    p = Participant(client, store.participants()[0]["token"], rate=lambda item: "a")
    for _ in range(4):
        p.step()
    page = p.get()
    assert "Waiting for the next question" in page and "robot" not in page.lower()
    assert "The next pair of clips of your car will appear here" in page
    store, client = _live(tmp_path / "t", waiting="Please wait for the next pair.")
    assert "Please wait for the next pair." in _waiting(client, store).get()
    store, client = _live(tmp_path / "u")
    assert "The robot is still learning" in _waiting(client, store).get()

"""The participant flow, the dashboard and bad input, in process (starlette's TestClient)."""

import dataclasses
import html
import json
import re

import pytest
from fastapi.testclient import TestClient
from study_helpers import ADMIN, Participant, hidden, study_file

from mindgap.study.app import create_app
from mindgap.study.server import open_study

GRID = {"source": "random", "count": 3, "length": 10}


def _app(tmp_path, example="coffee-rating", **changes):
    changes.setdefault("participants", 3)
    study, store, renderer = open_study(study_file(tmp_path, example, **changes), tmp_path / "s.sqlite", ADMIN)
    return study, store, TestClient(create_app(study, store, renderer))


@pytest.fixture
def coffee(tmp_path):
    return _app(tmp_path, min_seconds=0)


def _to_items(client, token):
    """Consent, instructions and questionnaire done; returns the first item page."""
    p = Participant(client, token, rate=lambda item: 5)
    while 'name="item_id"' not in (page := p.get()):
        p.step()
    return page


def _rate(item):
    return 0 if item == "sanity-random" else 3 + len(item) % 7


def test_a_participant_completes_the_study_and_progress_survives_reloads(coffee):
    study, store, client = coffee
    token = store.participants()[0]["token"]
    p = Participant(client, token, rate=_rate)
    for _ in range(5):  # consent, instructions, questionnaire, two items
        p.step()
    page = p.get()
    again = hidden(p.get(), "item_id")
    assert again == hidden(page, "item_id")  # a reload shows the same item, not the first one
    order = json.loads(store.participants()[0]["item_order"])
    assert again == order[2]
    p.run()
    assert p.code == store.participants()[0]["completion_code"]
    assert sorted(p.acked) == sorted(order)
    rows = {a["item_id"]: a["value"] for a in store.answers()}
    assert rows == {item: float(_rate(item)) for item in order}
    assert all(a["seconds"] is not None and a["seconds"] >= 0 for a in store.answers())
    assert {q["question"]: q["value"] for q in store.questionnaire()} == {"q1": 3, "q2": 3}


def test_pictures_are_drawn_by_mindgap_and_served_only_to_their_participant(coffee):
    study, store, client = coffee
    a, b = (p["token"] for p in store.participants()[:2])
    page = _to_items(client, a)
    item = hidden(page, "item_id")
    steps = re.findall(rf'src="/p/{a}/media/{item}/(step-\d+)"', page)  # a coffee demonstration: one per step
    states = next(it for it in store.items() if it["id"] == item)["data"]["states"]
    assert steps == [f"step-{k}" for k in range(len(states))]
    for part in steps:
        img = client.get(f"/p/{a}/media/{item}/{part}")
        assert img.status_code == 200 and img.content[:8] == b"\x89PNG\r\n\x1a\n"
    for part in ("a", "demo", f"step-{len(steps)}", "step-01"):  # parts this item does not have
        assert client.get(f"/p/{a}/media/{item}/{part}").status_code == 404, part
    assert client.get(f"/p/{a}/media/no-such-item/step-0").status_code == 404
    assert client.get(f"/p/not-a-token/media/{item}/step-0").status_code == 404


def test_a_second_participant_cannot_answer_for_the_first(coffee):
    study, store, client = coffee
    a, b = (p["token"] for p in store.participants()[:2])
    page_a, page_b = _to_items(client, a), _to_items(client, b)
    form = {"item_id": hidden(page_a, "item_id"), "submission_id": "abcdefgh1234", "rating": "7"}
    # B's form token on A's page: refused
    r = client.post(f"/p/{a}/answer", data={**form, "csrf": hidden(page_b, "csrf")}, follow_redirects=False)
    assert r.status_code == 403
    # no form token at all: refused
    assert client.post(f"/p/{a}/answer", data=form, follow_redirects=False).status_code == 403
    # a cross-site post, even with the right token: refused
    r = client.post(
        f"/p/{a}/answer", data={**form, "csrf": hidden(page_a, "csrf")}, headers={"Origin": "http://evil.example"}
    )
    assert r.status_code == 403
    assert store.answers() == []


def test_bad_answers_get_clear_errors_and_are_not_stored(coffee):
    study, store, client = coffee
    token = store.participants()[0]["token"]
    page = _to_items(client, token)
    base = {"csrf": hidden(page, "csrf"), "item_id": hidden(page, "item_id"), "submission_id": "sub-000000001"}
    for bad in ("11", "-1", "nan", "seven"):
        r = client.post(f"/p/{token}/answer", data={**base, "rating": bad})
        assert r.status_code == 200 and "from 0 to 10" in _error(r.text), bad  # back on the item page
    r = client.post(f"/p/{token}/answer", data={**base, "item_id": "no-such-item", "rating": "5"})
    assert r.status_code == 404 and "no-such-item" in r.text
    order = json.loads(store.participants()[0]["item_order"])
    r = client.post(f"/p/{token}/answer", data={**base, "item_id": order[-1], "rating": "5"})
    assert r.status_code == 409  # not the item shown now
    r = client.post(f"/p/{token}/answer", data={**base, "submission_id": "x", "rating": "5"})
    assert r.status_code == 400
    assert client.get("/p/unknown-token").status_code == 404
    assert store.answers() == []


def test_a_double_click_records_one_answer(coffee):
    study, store, client = coffee
    token = store.participants()[0]["token"]
    page = _to_items(client, token)
    form = {"csrf": hidden(page, "csrf"), "item_id": hidden(page, "item_id"), "submission_id": "double-click-1"}
    outcomes = [
        client.post(f"/p/{token}/answer", data={**form, "rating": "6"}, follow_redirects=False) for _ in range(3)
    ]
    assert [r.status_code for r in outcomes] == [303, 303, 303]
    assert [r.headers["x-answer"] for r in outcomes] == ["stored", "duplicate", "duplicate"]
    # another tab with the same item and another submission id: the first answer stands
    r = client.post(
        f"/p/{token}/answer", data={**form, "submission_id": "other-tab-22", "rating": "1"}, follow_redirects=False
    )
    assert r.headers["x-answer"] == "answered"
    assert [(a["item_id"], a["value"]) for a in store.answers()] == [(form["item_id"], 6.0)]


def test_answers_faster_than_the_minimum_time_are_refused(tmp_path):
    study, store, client = _app(tmp_path, min_seconds=30)
    token = store.participants()[0]["token"]
    page = _to_items(client, token)
    assert 'data-wait="30' in page or 'data-wait="29' in page
    form = {
        "csrf": hidden(page, "csrf"),
        "item_id": hidden(page, "item_id"),
        "submission_id": "too-fast-001",
        "rating": "4",
    }
    r = client.post(f"/p/{token}/answer", data=form)
    assert r.status_code == 200 and "at least 30 seconds" in _error(r.text)  # back on the item page
    assert store.answers() == []


def test_dashboard_and_exports_need_the_admin_token(coffee):
    study, store, client = coffee
    for url in ("/admin", "/admin/api/status", "/admin/export/ratings.csv", "/admin/export/answers.json"):
        assert client.get(url).status_code == 401, url
        assert client.get(url, headers={"Authorization": "Bearer wrong"}).status_code == 401, url
    assert client.get("/admin", headers={"Authorization": f"Bearer {ADMIN}"}).status_code == 200
    r = client.get(f"/admin?token={ADMIN}", follow_redirects=False)  # sets a cookie and drops the token from the URL
    assert r.status_code == 303 and "samesite=strict" in r.headers["set-cookie"].lower()
    assert client.get("/admin").status_code == 200
    # adding participants is a form post: needs the dashboard's form token
    assert client.post("/admin/participants", data={"count": "2"}).status_code == 403
    page = client.get("/admin").text
    r = client.post("/admin/participants", data={"count": "2", "csrf": hidden(page, "csrf")}, follow_redirects=False)
    assert r.status_code == 303 and len(store.participants()) == 5
    r = client.post("/admin/participants", data={"count": "0", "csrf": hidden(page, "csrf")})
    assert r.status_code == 422


def test_dashboard_shows_progress_and_sanity_failures(coffee):
    study, store, client = coffee
    good, bad = (p["token"] for p in store.participants()[:2])
    Participant(client, good, rate=_rate).run()
    Participant(client, bad, rate=lambda item: 9 if item == "sanity-random" else 2).run()
    status = client.get("/admin/api/status", headers={"Authorization": f"Bearer {ADMIN}"}).json()
    people = {p["label"]: p for p in status["people"]}
    assert people["p-001"]["failed"] == [] and people["p-002"]["failed"] == ["sanity-random"]
    assert people["p-001"]["stage"] == people["p-002"]["stage"] == "done"
    assert people["p-003"]["stage"] == "consent" and people["p-003"]["answered"] == 0
    assert status["n_answers"] == 18 and status["n_failed"] == 1
    sanity_row = next(i for i in status["items"] if i["id"] == "sanity-random")
    assert sanity_row["answers"] == 2 and sanity_row["failures"] == 1
    html = client.get("/admin", headers={"Authorization": f"Bearer {ADMIN}"}).text
    assert "p-002" in html and "sanity-random" in html and people["p-001"]["code"] in html


def test_declining_consent_ends_the_study(coffee):
    study, store, client = coffee
    token = store.participants()[0]["token"]
    page = client.get(f"/p/{token}").text
    r = client.post(f"/p/{token}/consent", data={"csrf": hidden(page, "csrf"), "agree": "no"})
    assert r.status_code == 200 and "chose not to take part" in r.text
    assert "chose not to take part" in client.get(f"/p/{token}").text


def test_a_refused_consent_or_questionnaire_redirects_back_and_keeps_the_answers_given(coffee):
    study, store, client = coffee
    token = store.participants()[0]["token"]
    page = client.get(f"/p/{token}").text
    r = client.post(f"/p/{token}/consent", data={"csrf": hidden(page, "csrf")}, follow_redirects=False)
    assert r.status_code == 303 and r.headers["x-answer"] == "refused"  # Back and reload never resend it
    page = client.get(r.headers["location"]).text
    assert "Please say whether you agree to take part." in page and store.participants()[0]["consent_at"] is None
    client.post(f"/p/{token}/consent", data={"csrf": hidden(page, "csrf"), "agree": "yes"})
    page = client.get(f"/p/{token}").text
    client.post(f"/p/{token}/instructions", data={"csrf": hidden(page, "csrf")})
    page = client.get(f"/p/{token}").text
    assert "A few questions first" in page
    # q1 answered, q2 not: refused, q2 named, q1's answer kept on the page
    r = client.post(f"/p/{token}/questionnaire", data={"csrf": hidden(page, "csrf"), "q1": "4"}, follow_redirects=False)
    assert r.status_code == 303 and r.headers["x-answer"] == "refused"
    page = client.get(r.headers["location"]).text
    assert "Please answer every question (question 2: choose" in page  # its place, not the id
    assert re.search(r'name="q1" value="4" required checked', page)
    assert not re.search(r'name="q2" value="\d" required checked', page)
    assert store.questionnaire() == []
    # an answer off the scale is no answer
    r = client.post(f"/p/{token}/questionnaire", data={"csrf": hidden(page, "csrf"), "q1": "4", "q2": "99"})
    assert "Please answer every question (question 2: choose" in r.text and store.questionnaire() == []
    r = client.post(f"/p/{token}/questionnaire", data={"csrf": hidden(page, "csrf"), "q1": "4", "q2": "2"})
    assert {q["question"]: q["value"] for q in store.questionnaire()} == {"q1": 4, "q2": 2}


def test_pages_carry_security_headers(coffee):
    study, store, client = coffee
    r = client.get(f"/p/{store.participants()[0]['token']}")
    assert r.headers["referrer-policy"] == "no-referrer"  # the personal link must not leak to other sites
    assert "frame-ancestors 'none'" in r.headers["content-security-policy"]
    assert r.headers["cache-control"] == "no-store"


def test_comparison_items_show_two_pictures_and_take_a_choice(tmp_path):
    study, store, client = _app(tmp_path, "terrain-preference", min_seconds=0, questionnaire=[])
    store_items = {it["id"]: it for it in store.items()}
    token = store.participants()[0]["token"]
    page = _to_items(client, token)
    item = hidden(page, "item_id")
    assert store_items[item]["kind"] == "pair"
    for part in ("a", "b"):
        img = client.get(f"/p/{token}/media/{item}/{part}")
        assert img.status_code == 200 and img.content[:4] == b"\x89PNG"
    form = {"csrf": hidden(page, "csrf"), "item_id": item, "submission_id": "choice-0001"}
    r = client.post(f"/p/{token}/answer", data={**form, "choice": "c"}, follow_redirects=False)
    assert _error(client.get(_refused(r, token)).text) == "Please choose A, B or can't tell."
    kept = client.get(f"/p/{token}?item={item}&refused=choice&choice=b").text  # a refused choice comes back
    assert re.search(r'value="b" id="choice-b"[^>]* checked', kept) and _error(kept).startswith("Please choose")
    r = client.post(f"/p/{token}/answer", data={**form, "choice": "equal"}, follow_redirects=False)
    assert r.status_code == 303
    assert [(a["choice"], a["value"]) for a in store.answers()] == [("equal", 0.5)]
    assert dataclasses.asdict(study)["protocol"] == "preference"


def test_a_new_store_under_an_old_name_serves_its_own_pictures(tmp_path):
    def first_picture(seed, db):
        config = study_file(tmp_path, "grid7-rating", participants=1, min_seconds=0, items={**GRID, "seed": seed})
        study, store, renderer = open_study(config, db, ADMIN)
        client = TestClient(create_app(study, store, renderer))
        token = store.participants()[0]["token"]
        item = store.items()[0]["id"]
        img = client.get(f"/p/{token}/media/{item}/demo")
        assert img.status_code == 200
        store.close()
        return item, img.content

    db = tmp_path / "same-name.sqlite"
    item0, old = first_picture(0, db)
    for f in tmp_path.glob("same-name.sqlite*"):  # the researcher deletes the store, not its pictures
        if f.is_file():
            f.unlink()
    item1, new = first_picture(1, db)
    _, fresh = first_picture(1, tmp_path / "elsewhere.sqlite")
    assert item0 == item1  # the same item id with another path
    assert new == fresh and new != old


def test_a_form_without_a_length_is_read_only_up_to_the_limit(coffee):
    study, store, client = coffee
    token = store.participants()[0]["token"]
    csrf = hidden(client.get(f"/p/{token}").text, "csrf")
    chunks = iter([f"csrf={csrf}&agree=yes&pad=".encode(), b"a" * 40_000, b"a" * 40_000])  # sent chunked
    r = client.post(
        f"/p/{token}/consent", content=chunks, headers={"Content-Type": "application/x-www-form-urlencoded"}
    )
    assert r.status_code == 413 and "at most 64 KiB" in r.text
    r = client.post(f"/p/{token}/consent", files={"agree": ("agree.txt", b"yes")}, data={"csrf": csrf})
    assert r.status_code == 415  # the pages send URL-encoded forms only
    assert store.participant(token)["consent_at"] is None
    r = client.post(f"/p/{token}/consent", data={"csrf": csrf, "agree": "yes"}, follow_redirects=False)
    assert r.status_code == 303 and store.participant(token)["consent_at"] is not None


def _range_tag(page: str) -> str:
    m = re.search(r'<input type="range"[^>]*>', page)
    assert m, page[:2000]
    return m.group(0)


def _error(page: str) -> str:
    """The error message a page shows ('' when none)."""
    m = re.search(r'<p class="error" role="alert">([^<]*)</p>', page)
    return html.unescape(m.group(1)) if m else ""


def _refused(r, token):
    """A refused answer: 303 back to the participant's page, marked ``X-Answer: refused``."""
    assert r.status_code == 303 and r.headers["x-answer"] == "refused", (r.status_code, r.text[:300])
    assert r.headers["location"].startswith(f"/p/{token}?")
    return r.headers["location"]


def test_the_slider_has_no_value_until_it_is_moved_and_an_answer_without_one_is_refused(coffee):
    study, store, client = coffee
    token = store.participants()[0]["token"]
    page = _to_items(client, token)
    slider = _range_tag(page)
    assert "value=" not in slider and "name=" not in slider  # nothing is sent until the participant moves it
    assert re.search(r'id="rating-value">\s*–\s*<', page)
    form = {"csrf": hidden(page, "csrf"), "item_id": hidden(page, "item_id"), "submission_id": "untouched-1"}
    for missing in ({}, {"rating": ""}):
        where = _refused(client.post(f"/p/{token}/answer", data={**form, **missing}, follow_redirects=False), token)
        again = client.get(where)
        assert (
            again.status_code == 200
            and _error(again.text) == "Please move the slider to give your rating (from 0 to 10)."
        )
        assert hidden(again.text, "item_id") == form["item_id"]
    assert store.answers() == []


def test_ratings_must_be_plain_numbers_on_the_scales_steps(tmp_path):
    study, store, client = _app(tmp_path, "grid7-rating", min_seconds=0, rating={"min": 1, "max": 7, "step": 0.5})
    token = store.participants()[0]["token"]
    page = _to_items(client, token)
    form = {"csrf": hidden(page, "csrf"), "item_id": hidden(page, "item_id"), "submission_id": "strict-0001"}
    for bad in ("6.25", "1e1", "0.5", "7.5", "nan", "inf", "seven", " 6", "6.", ".5", "0x6", "+6", "6,5", "１"):
        where = _refused(client.post(f"/p/{token}/answer", data={**form, "rating": bad}, follow_redirects=False), token)
        assert _error(client.get(where).text) == "The rating must be a number from 1 to 7 in steps of 0.5.", bad
    assert store.answers() == []
    r = client.post(f"/p/{token}/answer", data={**form, "rating": "6.50"}, follow_redirects=False)
    assert r.status_code == 303 and r.headers["x-answer"] == "stored"
    assert [a["value"] for a in store.answers()] == [6.5]


def test_a_step_1_scale_refuses_halves(coffee):
    study, store, client = coffee
    token = store.participants()[0]["token"]
    page = _to_items(client, token)
    form = {"csrf": hidden(page, "csrf"), "item_id": hidden(page, "item_id"), "submission_id": "half-00001"}
    for bad in ("5.5", "1e1", "10e0"):
        r = client.post(f"/p/{token}/answer", data={**form, "rating": bad}, follow_redirects=False)
        assert _error(client.get(_refused(r, token)).text) == "The rating must be a number from 0 to 10 in steps of 1."
    assert store.answers() == []


def test_a_refused_answer_comes_back_as_its_item_page_with_the_message_and_the_chosen_value(tmp_path):
    study, store, client = _app(tmp_path, min_seconds=30)
    token = store.participants()[0]["token"]
    page = _to_items(client, token)
    item = hidden(page, "item_id")
    form = {"csrf": hidden(page, "csrf"), "item_id": item, "submission_id": "too-fast-0001", "rating": "7"}
    where = _refused(client.post(f"/p/{token}/answer", data=form, follow_redirects=False), token)
    again = client.get(where)  # post/redirect/get: a reload or Back shows this page again, no resubmission
    assert again.status_code == 200 and _error(again.text) == "Please take at least 30 seconds to look at each item."
    assert hidden(again.text, "item_id") == item
    slider = _range_tag(again.text)
    assert 'value="7"' in slider and 'name="rating"' in slider  # the chosen value is kept
    assert re.search(r'id="rating-value">\s*7\s*<', again.text)
    # the address is checked, not echoed: another item's refusal or a made-up value shows nothing
    for query in ("item=sunny-nothing&refused=too-fast&rating=7", f"item={item}&refused=made-up&rating=<b>"):
        shown = client.get(f"/p/{token}?{query}").text
        assert _error(shown) == "" and "<b>" not in shown and "value=" not in _range_tag(shown)
    assert store.answers() == []


def test_dashboard_links_use_the_public_address_not_the_requests_host(tmp_path):
    study, store, renderer = open_study(study_file(tmp_path, "coffee-rating", participants=2), tmp_path / "u.sqlite")
    client = TestClient(create_app(study, store, renderer, public_url="https://study.example.org/lab"))
    admin = {"Authorization": f"Bearer {store.meta('admin_token')}", "Host": "evil.example"}
    people = client.get("/admin/api/status", headers=admin).json()["people"]
    assert [p["link"] for p in people] == [
        f"https://study.example.org/lab/p/{p['token']}" for p in store.participants()
    ]
    assert "evil.example" not in client.get("/admin", headers=admin).text
    for bad in ("study.example.org", "ftp://study.example.org", "https://study.example.org/?x=1", "https://"):
        with pytest.raises(ValueError, match="public address"):
            create_app(study, store, renderer, public_url=bad)

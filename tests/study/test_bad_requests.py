"""Hand-made requests get a short page with a 4xx (or the participant's own page), never a 500;
a withdrawal takes a participant's answers out of every export."""

import json

import pytest
from fastapi.testclient import TestClient
from study_helpers import ADMIN, Participant, hidden, study_file

from mindgap.study import export
from mindgap.study.app import create_app
from mindgap.study.server import open_study


def _app(tmp_path, public_url="http://127.0.0.1:8000", **changes):
    tmp_path.mkdir(parents=True, exist_ok=True)
    changes = {"participants": 2, "min_seconds": 0, **changes}
    study, store, renderer = open_study(study_file(tmp_path, "coffee-rating", **changes), tmp_path / "s.sqlite", ADMIN)
    client = TestClient(create_app(study, store, renderer, public_url=public_url), raise_server_exceptions=False)
    return store, client


@pytest.fixture
def coffee(tmp_path):
    return _app(tmp_path)


def _past_questionnaire(client, token) -> Participant:
    p = Participant(client, token, rate=lambda item: 5)
    for _ in range(3):  # consent, instructions, questionnaire
        p.step()
    return p


@pytest.mark.parametrize("refused", ["consent", "questionnaire", "questionnaire&q1=3&q2=9"])
def test_an_old_refusal_address_shows_the_participant_s_current_page(coffee, refused):
    """The address a refused consent or questionnaire redirected to, visited again after that step
    (Back, a bookmark): the current page, the old message not repeated."""
    store, client = coffee
    p = _past_questionnaire(client, store.participants()[0]["token"])
    r = client.get(f"/p/{p.token}?refused={refused}")
    assert r.status_code == 200 and 'name="item_id"' in r.text and 'class="error"' not in r.text


@pytest.mark.parametrize(
    "how",
    [
        {"headers": {"Authorization": "Bearer é-token".encode()}},
        {"params": {"token": "tökén"}},
        {"headers": {"Cookie": "mindgap_admin=\u00e9t\u00e9".encode()}},
    ],
    ids=["header", "query", "cookie"],
)
def test_a_non_ascii_admin_token_is_refused(coffee, how):
    store, client = coffee
    for url in ("/admin", "/admin/export/answers.csv"):
        r = client.get(url, **how)
        assert r.status_code == 401 and "Researchers only" in r.text, url


def test_a_non_ascii_form_token_is_refused(coffee):
    store, client = coffee
    token = store.participants()[0]["token"]
    r = client.post(f"/p/{token}/consent", data={"csrf": "ünïcode", "agree": "yes"})
    assert r.status_code == 403 and "Form expired" in r.text
    admin = {"Authorization": f"Bearer {ADMIN}"}
    r = client.post("/admin/participants", data={"csrf": "ünïcode", "count": "1"}, headers=admin)
    assert r.status_code == 403 and store.participant(token)["consent_at"] is None


@pytest.mark.parametrize("value", ["³", "٣", "3.0", "99", ""])
def test_a_questionnaire_answer_that_is_no_number_on_the_scale_is_refused(coffee, value):
    store, client = coffee
    token = store.participants()[0]["token"]
    p = Participant(client, token, rate=lambda item: 5)
    p.step(), p.step()  # consent, instructions
    page = p.get()
    r = p.post("questionnaire", {"csrf": hidden(page, "csrf"), "q1": "4", "q2": value})
    assert r.status_code == 303 and r.headers["x-answer"] == "refused"
    again = client.get(r.headers["location"])
    assert again.status_code == 200 and "Please answer every question (question 2: choose 1–5)." in again.text
    assert client.get(f"/p/{token}?refused=questionnaire&q1={value}&q2={value}").status_code == 200
    assert store.questionnaire() == []


def test_a_participant_who_declines_after_answering_is_in_no_export(coffee):
    store, client = coffee
    a, b = (p["token"] for p in store.participants())
    Participant(client, a, rate=lambda item: 4).run()
    p = _past_questionnaire(client, b)
    p.step(), p.step()  # two answers
    # "I do not agree" on the consent page still open in another tab (every form of theirs has one token)
    page = p.get()
    r = p.post("consent", {"csrf": hidden(page, "csrf"), "agree": "no"})
    assert r.status_code == 303
    form = {k: hidden(page, k) for k in ("csrf", "item_id", "submission_id")}
    r = p.post("answer", {**form, "rating": "5"})  # the item page left open: back to their page, not stored
    assert r.status_code == 303 and r.headers["location"] == f"/p/{b}"
    assert sum(x["participant"] == "p-002" for x in store.answers()) == 2
    assert "chose not to take part" in client.get(f"/p/{b}").text
    for partial in (False, True):
        assert "p-002" not in export.ratings_csv(store, partial)
    assert "p-002" not in export.answers_csv(store)
    raw = json.loads(export.answers_json(store))
    assert {x["participant"] for x in raw["answers"]} == {"p-001"}
    assert next(x for x in raw["participants"] if x["participant"] == "p-002")["questionnaire"] == {}
    admin = {"Authorization": f"Bearer {ADMIN}"}
    assert "p-002" not in client.get("/admin/export/ratings.csv?partial=true", headers=admin).text


def test_the_admin_cookie_is_secure_when_the_public_url_is_https(tmp_path):
    store, client = _app(tmp_path / "https", public_url="https://study.example.org/lab")
    r = client.get(f"/admin?token={ADMIN}", follow_redirects=False)
    assert r.status_code == 303 and r.headers["location"] == "/lab/admin"
    assert "secure" in [x.strip().lower() for x in r.headers["set-cookie"].split(";")]
    store, client = _app(tmp_path / "http")
    r = client.get(f"/admin?token={ADMIN}", follow_redirects=False)
    assert "secure" not in r.headers["set-cookie"].lower()

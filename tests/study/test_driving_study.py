"""The driving study of §4.4.2 with people: its study files, its animations, both phases, and their exports."""

import csv
import io
import json
import re
import threading
import time

import numpy as np
import pytest
from fastapi.testclient import TestClient
from PIL import Image
from study_helpers import Participant, driving_rollouts, hidden, study_file

from mindgap.cli import main
from mindgap.data.rollouts_file import RolloutsFileError, read_rollouts
from mindgap.data.segments import SHOWN, Segments
from mindgap.envs.driving import FEATURES, importance_weights, make_world
from mindgap.envs.driving.sleet import factor_mean_std
from mindgap.study import driving as sd
from mindgap.study.app import create_app
from mindgap.study.config import StudyFileError, load_study
from mindgap.study.driving import scripted_segment
from mindgap.study.export import export_all
from mindgap.study.live import StudyTeacher
from mindgap.study.server import open_study

pytest.importorskip("highway_env", reason="the driving animations are drawn by highway-env (mindgap[driving])")


def test_a_driving_study_file_is_checked_key_by_key(tmp_path):
    bad = [
        ({"domain": {"name": "driving", "sleet": 1.5}}, "domain.sleet must be a number from 0"),
        ({"domain": {"name": "driving", "sleet": "wet"}}, "domain.sleet must be a number from 0"),
        ({"domain": {"name": "driving", "lanes": 4}}, "domain.lanes is not a key of the driving domain"),
        ({"domain": {"name": "driving", "traffic": 1.5}}, "domain.traffic must be a whole number"),
        ({"domain": {"name": "driving", "brake_first": 5, "brake_last": 2}}, "domain: brake_window must satisfy"),
        ({"items": {"source": "live", "fixed": ["bias", "crash"]}}, "items.fixed must list some of bias, sanity"),
        ({"items": {"source": "live", "segment": 40}}, "items.segment must be a whole number of steps from 2 to 15"),
        (
            {"items": {"source": "random-pairs"}},
            "items.source 'random-pairs' does not fit domain driving: use live, file",
        ),
        ({"protocol": "rating"}, "live driving studies compare segments: protocol preference or expectation"),
        ({"items": {"source": "file"}, "protocol": "rating"}, "items.path must name a rollouts file"),
        ({"items": {"source": "file", "path": "r.json"}}, "driving studies from a rollouts file rate whole episodes"),
    ]
    for change, message in bad:
        with pytest.raises(StudyFileError, match=re.escape(message)):
            load_study(study_file(tmp_path, "driving-training", **change))
    assert load_study(study_file(tmp_path, "driving-training")).domain == {"name": "driving", "sleet": 1.0}


def test_the_bias_question_brakes_at_dry_and_at_sleet_grip_and_the_sanity_item_shows_a_collision(tmp_path):
    study, store, _ = open_study(study_file(tmp_path, "driving-training"), tmp_path / "t.sqlite")
    items = {it["id"]: it for it in store.items()}
    assert list(items) == ["bias", "sanity"] and items["sanity"]["sanity"]["rule"] == "answer"
    bias, sanity = items["bias"]["data"], items["sanity"]["data"]
    good, other = bias[bias["effective"]], bias["b" if bias["effective"] == "a" else "a"]
    assert good["obs"][0] == other["obs"][0] and good["act"][:2] == other["act"][:2]  # the same start and braking
    # the same braking: at dry grip the car slows more in its first braking second than at sleet grip
    v = lambda seg: np.asarray(seg["next_obs"])[:, 2] * 30  # noqa: E731
    assert v(good)[1] < v(other)[1] < v(good)[0]
    p = make_world(sleet=1.0).params
    dry, wet = (float(factor_mean_std(s, p.grip)[0]) for s in (0.0, 1.0))
    assert (good, other) == (scripted_segment(p, dry, True, 6), scripted_segment(p, wet, True, 6))
    crashed = lambda seg: max(o[6] for o in seg["next_obs"]) > 0.5  # noqa: E731
    safe = sanity[sanity["safe"]]
    assert items["sanity"]["sanity"]["value"] == sanity["safe"] and not crashed(safe)
    assert crashed(sanity["b" if sanity["safe"] == "a" else "a"])


def _gif_frames(client, url) -> int:
    r = client.get(url)
    assert r.status_code == 200 and r.headers["content-type"] == "image/gif", r.status_code
    return Image.open(io.BytesIO(r.content)).n_frames


def _gif_seconds(client, url) -> float:
    """A GIF's length: the sum of its frames' durations."""
    with Image.open(io.BytesIO(client.get(url).content)) as im:
        return sum((im.seek(k), im.info["duration"])[1] for k in range(im.n_frames)) / 1000


def _gif_rgb(path) -> list[np.ndarray]:
    """A GIF's frames as [H, W, 3] int arrays, each held frame once per 70 ms of its duration."""
    with Image.open(path) as im:
        out = []
        for k in range(im.n_frames):
            im.seek(k)
            out += [np.asarray(im.convert("RGB"), int)] * round(im.info["duration"] / 70)
        return out


def _box(frame: np.ndarray, rgb, tol: int = 12):
    """(x0, x1, y0, y1) of the pixels within ``tol`` of ``rgb``."""
    ys, xs = np.nonzero(np.abs(frame - np.asarray(rgb)).max(-1) <= tol)
    return xs.min(), xs.max(), ys.min(), ys.max()


def _brake_light_px(frame: np.ndarray, box) -> int:
    """Brake-light red pixels at the back (left end) of a car's box."""
    x0, _, y0, y1 = box
    part = frame[y0 : y1 + 1, max(0, x0 - 3) : x0 + 14]
    return int(((part[..., 0] > 220) & (part[..., 1] < 60) & (part[..., 2] < 60)).sum())


EGO, FRONT = (50, 200, 0), (100, 200, 255)


def test_driving_clips_show_large_cars_brake_lights_and_loop_in_step(tmp_path):
    """Issue 49: the cars were 25 px long with no brake lights, and a pair's clips lasted 4.6 and 5.5 s."""
    study, store, renderer = open_study(study_file(tmp_path, "driving-training"), tmp_path / "t.sqlite")
    item = next(it for it in store.items() if it["id"] == "sanity")
    safe, crash = item["data"]["safe"], "b" if item["data"]["safe"] == "a" else "a"
    clips = {side: _gif_rgb(renderer.path(item, side, "")) for side in "ab"}
    assert len(clips["a"]) == len(clips["b"]) == 1 + 15 * 6 + 10  # the crash (5 steps) held to the safe one's length
    start = clips[safe][0]
    x0, x1, y0, y1 = _box(start, EGO)
    assert x1 - x0 + 1 >= 60 and start.shape[1] >= 800  # a 5 m car is 68 px (inside its outline)
    fx0 = _box(start, FRONT)[0]
    assert fx0 > x1 and fx0 < start.shape[1] - 60  # the front car in view ahead, with room for it to pull away
    # the front car brakes from the first decision, the ego from the second (the crash's ego never does)
    assert _brake_light_px(start, (x0, x1, y0, y1)) == 0 and _brake_light_px(start, _box(start, FRONT)) == 0
    frame = clips[safe][8]
    assert _brake_light_px(frame, _box(frame, FRONT)) >= 100 and _brake_light_px(frame, _box(frame, EGO)) == 0
    frame = clips[safe][1 + 15 + 7]
    assert _brake_light_px(frame, _box(frame, EGO)) >= 100
    frame = clips[crash][1 + 15 + 7]
    assert _brake_light_px(frame, _box(frame, EGO)) == 0 and _brake_light_px(frame, _box(frame, FRONT)) >= 100


def test_a_sleety_road_looks_sleety_and_a_dry_one_does_not(tmp_path):
    seg = scripted_segment(make_world(sleet=1.0).params, 0.95, True, 2)
    looks = {}
    for sleet in (1.0, 0.0):
        study = load_study(study_file(tmp_path, "driving-training", domain={"name": "driving", "sleet": sleet}))
        frame = np.asarray(sd.frames(study, seg)[0], int)
        verge = frame[:5].reshape(-1, 3).mean(0)  # the ground above the road
        road = frame[frame.shape[0] // 2 + 45 : frame.shape[0] // 2 + 70]  # the lane below the ego's
        streaks = int((road.min(-1) > 200).sum())  # light pixels on the road surface off the lane lines
        looks[sleet] = (verge, streaks)
    (snow, sleety), (grass, dry) = looks[1.0], looks[0.0]
    assert snow.min() > 200 and grass[1] > grass[0] + 20 and grass[1] > grass[2] + 20  # white verge vs green
    assert sleety > 100 and dry < sleety / 5


def _segments(item_data: dict) -> tuple[Segments, Segments]:
    return tuple(
        Segments(*(np.asarray([item_data[s][f]], bool if f == "mask" else np.float32) for f in SHOWN))
        for s in ("a", "b")
    )


IMPORTANCE = {"p-001": (3, 5, 2, 4), "p-002": (4, 5, 3, 3), "p-003": (1, 1, 1, 1)}


def test_the_training_phase_end_to_end_in_process(tmp_path):
    """Three participants: the questionnaire, the bias question, the sanity item (p-003 fails it), then a live
    query that a run posts; the export gives the valid people's importances, the bias count and the live answers."""
    config = study_file(tmp_path, "driving-training", participants=3, min_seconds=0)
    study, store, renderer = open_study(config, tmp_path / "train.sqlite")
    client = TestClient(create_app(study, store, renderer))
    items = {it["id"]: it for it in store.items()}
    eff, safe = items["bias"]["data"]["effective"], items["sanity"]["data"]["safe"]
    other = {"a": "b", "b": "a"}
    people = []
    for p in store.participants():
        label = p["label"]
        choose = {"bias": eff if label != "p-002" else other[eff], "sanity": safe if label != "p-003" else other[safe]}
        who = Participant(client, p["token"], lambda item, c=choose: c.get(item, "a"))
        who.step()  # consent
        who.step()  # instructions
        page = who.get()
        assert "distance with front car" in page and "NOT care" in page and "Strongly care" in page
        answers = dict(zip(FEATURES, map(str, IMPORTANCE[label])))
        r = who.post("questionnaire", {"csrf": hidden(page, "csrf"), **answers})
        assert r.status_code == 303
        people.append(who)
    page = people[0].get()
    assert ("How will your car brake?" in page) == (hidden(page, "item_id") == "bias")
    media = sorted(set(re.findall(r'/p/[^"]+/media/[^"]+', page)))
    assert len(media) == 2 and 'class="pictures pair wide"' in page  # one clip above the other, each at full size
    item = hidden(page, "item_id")
    # highway-env's animation: the start and 15 frames per real decision, the shorter held on its last frame
    lengths = [1 + 15 * sum(items[item]["data"][side]["mask"]) for side in "ab"]
    for url, n in zip(media, lengths):
        assert _gif_frames(client, url) == n
    assert [_gif_seconds(client, url) for url in media] == [pytest.approx(0.07 * (max(lengths) + 10))] * 2
    for who in people:
        who.step(), who.step()  # the bias question and the sanity item, in each one's order
    assert "Waiting for the next question" in people[0].get()

    # a run (EPS's host teacher) posts one query; p-001 answers it
    world = make_world(sleet=1.0)
    teacher = StudyTeacher(store.path, world, timeout=60, poll=0.02, progress=False)
    seg_a, seg_b = _segments(items["bias"]["data"])
    got = {}
    run = threading.Thread(target=lambda: got.update(zip(("labels", "answered"), teacher(seg_a, seg_b))))
    run.start()
    deadline = time.monotonic() + 30
    while 'name="item_id"' not in (page := people[0].get()) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert "matches your expectation more" in page
    people[0].step()  # answers "a"
    run.join(30)
    assert got["answered"].tolist() == [True] and got["labels"].tolist() == [1.0]
    for who in people:
        r = who.post("finish", {"csrf": hidden(who.get(), "csrf")})
        assert r.status_code == 303

    out = tmp_path / "export"
    export_all(store, out)
    prefs = json.loads((out / "preferences.json").read_text())
    assert prefs["protocol"] == "expectation" and prefs["domain"] == {"name": "driving", "sleet": 1.0}
    assert [r["answer"] for r in prefs["records"]] == ["a"]  # the live query only: the fixed items are no data
    s = sd.training_summary(out / "answers.json")
    assert s["valid"] == 2 and s["participants"] == 3  # p-003 failed the sanity item
    want = np.mean([IMPORTANCE["p-001"], IMPORTANCE["p-002"]], 0)
    assert np.allclose(list(s["importance"].values()), want)
    assert np.allclose(list(s["weights"].values()), importance_weights(want))
    assert (s["bias_effective"], s["bias_answered"]) == (1, 2)
    assert main(["study", "driving", "--answers", str(out / "answers.json"), "--out", str(tmp_path / "s.json")]) == 0
    line = json.loads((tmp_path / "s.json").read_text())["training"]["reproduce"]
    assert line == "mindgap reproduce driving --importance 3.5,5,2.5,3.5"


RATINGS = {"p-001": {"eps-s0-e0": 8, "sac-s0-e0": 4, "sanity": 1}, "p-002": {"eps-s0-e0": 6, "sac-s0-e0": 5, "sanity": 2},
           "p-003": {"eps-s0-e0": 1, "sac-s0-e0": 9, "sanity": 5}}  # fmt: skip


def test_the_testing_phase_rates_a_rollouts_file_and_gives_table_5_s_ratings(tmp_path):
    driving_rollouts(tmp_path / "rollouts.json")
    assert len(read_rollouts(tmp_path / "rollouts.json")["records"]) == 3
    config = study_file(tmp_path, "driving-testing", participants=3, min_seconds=0)
    study, store, renderer = open_study(config, tmp_path / "test.sqlite")
    client = TestClient(create_app(study, store, renderer))
    for p in store.participants():
        who = Participant(client, p["token"], lambda item, r=RATINGS[p["label"]]: r[item])
        if p["label"] == "p-001":
            who.step(), who.step()
            page = who.get()
            url = re.findall(r'/p/[^"]+/media/[^"]+', page)
            assert len(url) == 1
            item = next(it for it in store.items() if it["id"] == hidden(page, "item_id"))
            assert _gif_frames(client, url[0]) == 1 + 15 * sum(item["data"]["segment"]["mask"])
        who.run()
    out = tmp_path / "export"
    export_all(store, out)
    rows = list(csv.DictReader((out / "ratings.csv").open()))
    assert {(r["participant"], r["item"]): float(r["rating"]) for r in rows} == {
        (who, item): v for who, r in RATINGS.items() for item, v in r.items()
    }
    s = sd.testing_summary(out / "ratings.csv")
    assert s["dropped"] == ["p-003"] and s["raters"] == 2  # rated the collision above a rollout
    assert s["methods"]["eps"]["rating_mean"] == pytest.approx(7.0) and s["methods"]["sac"]["rating_mean"] == 4.5
    assert s["methods"]["eps"]["rating_std"] == pytest.approx(1.0) and "sanity" not in s["methods"]
    assert main(["study", "driving", "--ratings", str(out / "ratings.csv")]) == 0


def test_a_rollouts_file_of_another_road_or_shape_is_refused(tmp_path):
    driving_rollouts(tmp_path / "rollouts.json", sleet=0.5)
    with pytest.raises(StudyFileError, match="^items.path: .* holds rollouts of"):
        open_study(study_file(tmp_path, "driving-testing"), tmp_path / "x.sqlite")
    doc = json.loads((tmp_path / "rollouts.json").read_text())
    doc["records"][1]["obs"] = doc["records"][1]["obs"][:-1]
    (tmp_path / "bad.json").write_text(json.dumps(doc))
    with pytest.raises(RolloutsFileError, match="record 1: obs must be 4 rows of 11 numbers"):
        read_rollouts(tmp_path / "bad.json")
    doc["records"][1]["item"] = doc["records"][0]["item"]
    (tmp_path / "bad.json").write_text(json.dumps(doc))
    with pytest.raises(RolloutsFileError, match="record 1: item 'eps-s0-e0' must be a unique name"):
        read_rollouts(tmp_path / "bad.json")


@pytest.mark.slow
def test_eps_learns_from_people_answering_the_driving_study_live(tmp_path):
    """``mindgap eps --fast --teacher study:STORE`` on the driving world while two scripted people answer
    through the app (after the fixed items): every query of the run is answered, and the answers are the
    study's export."""
    config = study_file(tmp_path, "driving-training", participants=2, min_seconds=0)
    study, store, renderer = open_study(config, tmp_path / "live.sqlite")
    client = TestClient(create_app(study, store, renderer))
    stop = threading.Event()

    def person(token):  # prefers the segment whose car ends slower: a braking person
        who = Participant(client, token, lambda item: "a")
        for _ in range(3):
            who.step()  # consent, instructions, questionnaire
        while not stop.is_set():
            page = who.get()
            if 'name="item_id"' not in page:
                time.sleep(0.05)
                continue
            item = hidden(page, "item_id")
            data = next((it["data"] for it in store.items() if it["id"] == item), None)
            if data is None:
                data = json.loads(store.live_query(int(item.split("-")[-1]))["data"])
            v = [np.asarray(data[s]["next_obs"])[np.asarray(data[s]["mask"])][-1, 2] for s in "ab"]
            choice = "a" if v[0] <= v[1] else "b"
            who.rate = lambda _item, c=choice: c
            who.step()

    people = [threading.Thread(target=person, args=(p["token"],), daemon=True) for p in store.participants()]
    for t in people:
        t.start()
    out = tmp_path / "run"
    argv = ["eps", "--env", "mindgap.envs.driving:make_world", "--fast", "--teacher", f"study:{store.path}"]
    try:
        assert main([*argv, "--answer-timeout", "120", "--quiet", "--out", str(out)]) == 0
    finally:
        stop.set()
        for t in people:
            t.join(10)
    summary = json.loads((out / "summary.json").read_text())
    counts = store.live_counts()
    assert counts["answered"] == summary["queries"] > 0 and counts.get("expired", 0) == 0
    export_all(store, tmp_path / "export", partial=True)
    prefs = json.loads((tmp_path / "export" / "preferences.json").read_text())
    assert len(prefs["records"]) == summary["queries"] and prefs["protocol"] == "expectation"

"""Studies on gymnasium envs: segments of a live run shown as animations the env draws itself."""

import io
import json
import re
import threading
import time

import numpy as np
import pytest
from fastapi.testclient import TestClient
from PIL import Image
from study_helpers import Participant, study_file

from mindgap.data.segments import SHOWN, Segments
from mindgap.envs.resolve import resolve_env
from mindgap.plotting.animation import observation_frames
from mindgap.study.app import create_app
from mindgap.study.config import StudyFileError, load_study
from mindgap.study.live import StudyTeacher
from mindgap.study.server import open_study

HOPPER = "gym:mindgap/NoisyHopper-v0"


def _segments(world, k: int = 2, length: int = 4, seed: int = 0) -> dict:
    """``k`` segments of random actions on ``world``'s env (the last one a step shorter: padded)."""
    rng = np.random.default_rng(seed)
    env, obs = world.make(seed)
    out = {f: [] for f in ("obs", "act", "next_obs", "mask")}
    try:
        for i in range(k):
            o, a, n, m = [], [], [], []
            for t in range(length):
                act = rng.uniform(-1, 1, len(world.act_low)).astype(np.float32)
                nxt, *_ = env.step(world.to_env(act))
                nxt = np.asarray(nxt, np.float32)
                real = not (i == k - 1 and t == length - 1)
                o.append(obs), a.append(act), n.append(nxt), m.append(real)
                obs = nxt
            for f, v in zip(out, (o, a, n, m)):
                out[f].append(v)
    finally:
        env.close()
    return {f: np.asarray(v) for f, v in out.items()}


def test_a_gym_study_must_compare_segments_of_a_gym_env(tmp_path):
    bad = [
        ({"protocol": "rating"}, "gym studies compare segments: protocol preference or expectation"),
        ({"domain": {"name": "gym"}}, "domain.env must name a gymnasium env as gym:ID"),
        ({"domain": {"name": "gym", "env": "nav1"}}, "domain.env must name a gymnasium env as gym:ID"),
        ({"items": {"source": "random-pairs"}}, "items.source 'random-pairs' does not fit domain gym: use live"),
    ]
    for change, message in bad:
        with pytest.raises(StudyFileError, match=message):
            load_study(study_file(tmp_path, "hopper-live", **change))
    # an env that cannot be made is refused when the study is opened, before any link exists
    config = study_file(tmp_path, "hopper-live", domain={"name": "gym", "env": "gym:NoSuchEnv-v9"})
    with pytest.raises(StudyFileError, match="^domain.env: gym:NoSuchEnv-v9: "):
        open_study(config, tmp_path / "bad.sqlite")
    assert not (tmp_path / "bad.sqlite.media").exists()
    # and so is an env whose observations do not hold its state (its segments could not be drawn)
    config = study_file(tmp_path, "hopper-live", domain={"name": "gym", "env": "gym:Hopper-v5"})
    with pytest.raises(StudyFileError, match="^domain.env: gym:Hopper-v5: an observation of 11 numbers"):
        open_study(config, tmp_path / "bad2.sqlite")


def test_frames_are_drawn_again_from_observations_and_other_envs_are_refused():
    world = resolve_env(HOPPER)
    seg = _segments(world, k=1, length=3)
    states = np.concatenate([seg["obs"][0, :1], seg["next_obs"][0]])
    frames = observation_frames(world, states)
    assert len(frames) == 4 and frames[0].ndim == 3 and frames[0].dtype == np.uint8
    assert not np.array_equal(frames[0], frames[-1])  # the robot moved
    # drawing the same state twice gives the same picture: the frame is the state's, not the env's history
    again = observation_frames(world, states[::-1])
    assert np.array_equal(again[-1], frames[0])
    with pytest.raises(ValueError, match="not the state's 6 positions and 6 velocities"):
        observation_frames(resolve_env("gym:Hopper-v5"), states[:, 1:])
    with pytest.raises(ValueError, match="cannot be drawn again from observations"):
        observation_frames(resolve_env("gym:Pendulum-v1"), np.zeros((2, 3)))


def test_a_live_hopper_pair_is_answered_through_the_app_with_animations(tmp_path):
    config = study_file(tmp_path, "hopper-live", participants=1, min_seconds=0, questionnaire=[])
    study, store, renderer = open_study(config, tmp_path / "hopper.sqlite")
    client = TestClient(create_app(study, store, renderer))
    world = resolve_env(HOPPER)
    teacher = StudyTeacher(store.path, world, timeout=60, poll=0.02, progress=False)
    seg = _segments(world, k=2, length=4)
    a, b = (Segments(*(np.asarray(seg[f][i : i + 1]) for f in SHOWN)) for i in (0, 1))
    result = {}
    run = threading.Thread(target=lambda: result.update(zip(("labels", "answered"), teacher(a, b))))
    run.start()  # the run posts the pair and waits for the answer
    p = Participant(client, store.participants()[0]["token"], lambda item: "b")
    p.step(), p.step()  # consent, instructions
    deadline = time.monotonic() + 30
    while 'name="item_id"' not in (page := p.get()) and time.monotonic() < deadline:
        time.sleep(0.05)
    media = sorted(set(re.findall(r'/p/[^"]+/media/[^"]+', page)))
    assert len(media) == 2
    for url, i in zip(media, (0, 1)):
        r = client.get(url)
        assert r.status_code == 200 and r.headers["content-type"] == "image/gif"
        gif = Image.open(io.BytesIO(r.content))
        assert gif.n_frames == int(seg["mask"][i].sum()) + 1  # the first state and each real step's arrival
    p.step()  # answers B
    run.join(30)
    assert result["answered"].tolist() == [True] and result["labels"].tolist() == [0.0]


def test_a_study_on_the_same_env_with_its_arguments_in_another_order_is_accepted(tmp_path):
    env = "gym:mindgap/NoisyHopper-v0,share=0.3,scale=0.4"
    config = study_file(tmp_path, "hopper-live", domain={"name": "gym", "env": env})
    study, store, _ = open_study(config, tmp_path / "h.sqlite")
    StudyTeacher(store.path, resolve_env("gym:mindgap/NoisyHopper-v0,scale=0.4,share=0.3"), progress=False)
    with pytest.raises(ValueError, match="the run trains on"):
        StudyTeacher(store.path, resolve_env("gym:mindgap/NoisyHopper-v0,share=0.3"), progress=False)
    assert json.loads(json.dumps(study.domain))["env"] == env

"""Preferences files and learning a reward from recorded answers offline."""

import argparse
import json

import jax
import numpy as np
import pytest
from study_helpers import study_file

from mindgap.checkpoint import load_pytree
from mindgap.envs.terrain import load_world
from mindgap.models.reward_ensemble import RewardConfig, reward_init, segment_returns
from mindgap.study import export
from mindgap.study.items import random_segments, true_returns
from mindgap.study.offline import run_offline
from mindgap.study.prefs_file import PreferencesFileError, read_preferences
from mindgap.study.server import open_study


def _answer_as_the_world_rewards(store, pids=(1, 2)):
    """Participants who prefer the segment with the higher return under the world's own reward."""
    world = load_world("nav1")
    items = store.items()
    seg = {
        s: {k: np.asarray([it["data"][s][k] for it in items]) for k in ("obs", "act", "next_obs", "mask")} for s in "ab"
    }
    diff = true_returns(world.params, seg["a"]) - true_returns(world.params, seg["b"])
    for pid in pids:
        for n, (it, d) in enumerate(zip(items, diff)):
            choice = "equal" if abs(d) < 1e-6 else ("a" if d > 0 else "b")
            store.record_answer(pid, it["id"], {"a": 1.0, "b": 0.0, "equal": 0.5}[choice], choice, f"s{pid}-{n:06d}")
        store.mark(pid, "completed")
    return diff


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("offline")
    config = study_file(
        tmp,
        "terrain-preference",
        participants=2,
        items={"source": "random-pairs", "pairs": 80, "segment": 10, "seed": 1},
    )
    study, store, _ = open_study(config, tmp / "s.sqlite")
    diff = _answer_as_the_world_rewards(store)
    path = tmp / "preferences.json"
    path.write_text(export.preferences_json(store))
    return tmp, path, diff


def test_the_export_is_a_preferences_file_with_every_answer(recorded):
    tmp, path, diff = recorded
    prefs = read_preferences(path)
    assert prefs.protocol == "preference" and prefs.domain == {"name": "terrain", "world": "nav1"}
    assert (prefs.segment, prefs.obs_dim, prefs.act_dim) == (10, 2, 2)
    assert len(prefs.records) == 2 * len(diff)
    seg_a, seg_b, labels = prefs.arrays()
    assert seg_a["obs"].shape == (2 * len(diff), 10, 2) and seg_a["mask"].dtype == bool
    want = np.where(np.abs(diff) < 1e-6, 0.5, (diff > 0).astype(float))
    assert np.array_equal(labels, np.concatenate([want, want]).astype(np.float32))


def test_a_reward_is_learned_offline_from_the_recorded_answers(recorded):
    tmp, path, _ = recorded
    out = tmp / "fit"
    args = argparse.Namespace(command="pebble", env="nav1", preferences=path, out=out, seed=0)
    assert run_offline(args) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["records"] == 160 and summary["participants"] == 2
    assert summary["answers_agree_with_world_reward"] == 1.0  # they answered by the world's reward
    assert summary["train_accuracy"] > 0.85
    assert (out / "reward.png").read_bytes()[:4] == b"\x89PNG"
    assert (out / "reward.npz").exists()


@pytest.mark.slow
def test_a_reward_learned_offline_ranks_unseen_segments_as_the_world_does(recorded):
    tmp, path, _ = recorded
    out = tmp / "fit-held-out"
    assert run_offline(argparse.Namespace(command="pebble", env="nav1", preferences=path, out=out, seed=1)) == 0
    world = load_world("nav1")
    template = reward_init(jax.random.key(0), 2, 2, RewardConfig()).params
    params, _ = load_pytree(out / "reward.npz", template)
    held_out = random_segments(jax.random.key(99), world.params, 400, 10)
    a = {k: v[:200] for k, v in held_out.items()}
    b = {k: v[200:] for k, v in held_out.items()}
    true = true_returns(world.params, a) - true_returns(world.params, b)

    def learned(s):
        from mindgap.data.segments import Segments

        return np.asarray(segment_returns(params, Segments(*(s[k] for k in ("obs", "act", "next_obs", "mask"))))).mean(
            0
        )

    guess = learned(a) - learned(b)
    clear = np.abs(true) > 0.5
    agree = np.mean((guess[clear] > 0) == (true[clear] > 0))
    assert agree > 0.75, agree  # chance is 0.5


@pytest.mark.parametrize(
    "edit, message",
    [
        (lambda d: d.update(format="other"), "not a preferences file"),
        (lambda d: d.update(version=7), "version 7 is not supported"),
        (lambda d: d["records"][0].update(label=2), "record 0: label 2 must be 1"),
        (lambda d: d["records"][1]["a"]["obs"].pop(), "record 1, segment a: obs must be 10 rows of 2 numbers"),
        (lambda d: d["records"][0]["b"]["mask"].__setitem__(0, False), "first step must be a real step"),
        (lambda d: d["records"][0]["b"]["act"][0].__setitem__(0, "x"), "not a finite number"),
    ],
)
def test_malformed_preferences_files_name_the_record(recorded, tmp_path, edit, message):
    _, path, _ = recorded
    doc = json.loads(path.read_text())
    edit(doc)
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(doc))
    with pytest.raises(PreferencesFileError) as e:
        read_preferences(bad)
    assert message in str(e.value)


def test_a_file_from_another_world_is_refused(recorded, tmp_path):
    _, path, _ = recorded
    args = argparse.Namespace(command="pebble", env="d1", preferences=path, out=tmp_path, seed=0)
    with pytest.raises(ValueError, match="recorded on world 'nav1'; pass --env nav1"):
        run_offline(args)

"""``mindgap reproduce gym --job DOMAIN/sac --reuse SOURCE``: a job the person never enters, taken from a run of
the same robot (:mod:`mindgap.experiments.gym_reuse`).

The default tests build the two run folders by hand (the belief fit stubbed): what the record keeps, what it
takes from this domain, and each refusal. The ``slow`` test trains SAC on ``cheetah`` and on ``cheetah-seen``
with the real ``--fast`` preset and checks that the records agree bit for bit in every field the training
makes, and the animations byte for byte: the reason the reuse is sound.
"""

import hashlib
import json
from dataclasses import replace

import pytest

from mindgap.cli import main
from mindgap.experiments import gym_reuse as gr
from mindgap.experiments import prefbias_gym as pg
from mindgap.experiments._runfolder import RunFolder, partial_path, record_path

SEEN = ("hopper-fixed-seen", "cheetah-seen")


@pytest.fixture
def source(tmp_path, monkeypatch):
    """A run folder of ``hopper-fixed`` (the fast preset) holding a whole SAC record and its animation; the
    belief fit stubbed to a record naming the domain's floor."""
    cfg = replace(pg.preset("fast"), worlds=("hopper-fixed",))
    root = tmp_path / "fixed"
    folder = RunFolder(root, cfg)
    (root / "rollouts").mkdir()
    (root / "rollouts/hopper-fixed__sac.gif").write_bytes(b"GIF89a-frames")
    record = {
        "seeds": cfg.seeds,
        "curve": [[0, 500, 12.5, 0], [0, 1500, 40.25, 0]],
        "final": [41.0],
        "paths": [[[[0.0, 1.25]]]],
        "belief_model": {"held_out_log_lik": 9.0, "path": "/elsewhere/cache.npz"},
        "rollout": "rollouts/hopper-fixed__sac.gif",
        "key": "hopper-fixed/sac",
        "world": "hopper-fixed",
        "method": "sac",
        "label": "SAC (oracle)",
        "seconds": 30.0,
        "command": "mindgap reproduce gym --fast --worlds hopper-fixed --out fixed --job hopper-fixed/sac",
    }
    folder.save("hopper-fixed/sac", record)

    def load_world(name, cfg, progress=False, cache_dir=None):
        return None, {"held_out_log_lik": 3.0, "person_min_std": pg.domain(name).person_min_std, "config": {}}

    monkeypatch.setattr(gr, "load_world", load_world)
    return root, record


def test_the_record_is_the_source_s_training_with_this_domain_s_person(source, tmp_path, capsys):
    root, base = source
    out = tmp_path / "seen"
    args = ["reproduce", "gym", "--fast", "--quiet", "--worlds", ",".join(SEEN), "--out", str(out)]
    assert main([*args, "--job", "hopper-fixed-seen/sac", "--reuse", str(root)]) == 0
    assert f"taken from {record_path(root, 'hopper-fixed/sac')}" in capsys.readouterr().out
    rec = json.loads(record_path(out, "hopper-fixed-seen/sac").read_text())
    assert gr.check_record(rec, base) == []
    assert (rec["curve"], rec["final"], rec["paths"], rec["seconds"]) == (
        base["curve"],
        base["final"],
        base["paths"],
        base["seconds"],
    )
    assert (rec["key"], rec["world"]) == ("hopper-fixed-seen/sac", "hopper-fixed-seen")
    assert rec["belief_model"] == {"held_out_log_lik": 3.0, "person_min_std": 1.0}  # this domain's person
    assert rec["command"].endswith(f"--job hopper-fixed-seen/sac --reuse {root}")
    text = record_path(root, "hopper-fixed/sac").read_text()
    assert rec["reused_from"] == {
        "run": str(root),
        "key": "hopper-fixed/sac",
        "sha256": hashlib.sha256(text.encode()).hexdigest(),
    }
    assert rec["rollout"] == "rollouts/hopper-fixed-seen__sac.gif"
    assert (out / rec["rollout"]).read_bytes() == b"GIF89a-frames"
    progress = json.loads((out / "progress.json").read_text())
    assert "hopper-fixed-seen/sac" not in progress["missing"] and "cheetah-seen/sac" in progress["missing"]
    # a training field that differs is named
    assert gr.check_record({**rec, "final": [40.0]}, base) == ["final"]


def test_what_cannot_be_reused_is_refused_with_one_line(source, tmp_path, capsys):
    root, _ = source
    out = tmp_path / "seen"
    fast = replace(pg.preset("fast"), worlds=SEEN)
    args = ["reproduce", "gym", "--fast", "--quiet", "--worlds", ",".join(SEEN), "--out", str(out)]
    other = tmp_path / "other-config"
    RunFolder(other, replace(pg.preset("fast"), worlds=("hopper-fixed",), seeds=2))
    no_twin = tmp_path / "cheetah-only"
    RunFolder(no_twin, replace(pg.preset("fast"), worlds=("cheetah",)))
    for extra, says in (
        (["--job", "hopper-fixed-seen/pebble-q30", "--reuse", str(root)], "is pebble"),
        (["--job", "hopper-fixed-seen/sac", "--reuse", str(tmp_path / "nowhere")], "is not a run folder"),
        (["--job", "hopper-fixed-seen/sac", "--reuse", str(other)], "ran another configuration than this run's"),
        (["--job", "hopper-fixed-seen/sac", "--reuse", str(no_twin)], "ran no domain with hopper-fixed-seen's robot"),
        (["--job", "cheetah-seen/sac", "--reuse", str(no_twin)], "has no whole record of cheetah/sac"),
        (["--job", "hopper-fixed-seen/sac", "--seed", "0", "--reuse", str(root)], "--reuse goes with gym and --job"),
        (["--reuse", str(root)], "--reuse goes with gym and --job"),
    ):
        assert main([*args, *extra]) == 2, extra
        err = capsys.readouterr().err
        assert says in err and err.count("\n") == 1 and "Traceback" not in err, err
        assert not out.exists()  # refused before the run folder is made
    assert main(["reproduce", "nav", "--fast", "--job", "nav1/sac", "--reuse", str(root)]) == 2
    assert "--reuse goes with gym" in capsys.readouterr().err
    # a job begun as slices, or done already, is not overwritten
    seed = partial_path(out, "hopper-fixed-seen/sac", 0)
    seed.parent.mkdir(parents=True)
    seed.write_text("{}")
    with pytest.raises(ValueError, match="trained apart"):
        gr.reuse(fast, out, "hopper-fixed-seen/sac", root)
    seed.unlink()
    gr.reuse(fast, out, "hopper-fixed-seen/sac", root)
    with pytest.raises(ValueError, match="has a record of hopper-fixed-seen/sac already"):
        gr.reuse(fast, out, "hopper-fixed-seen/sac", root)


def test_each_seen_domain_has_its_base_domain_s_robot_and_sac_job():
    """What makes the reuse sound without training: the robot and SAC's job are the same; the real training
    is compared in the slow test below."""
    full = pg.preset("full")
    for seen, base in zip(SEEN, ("hopper-fixed", "cheetah"), strict=True):
        assert gr.robot(seen) == gr.robot(base) and gr.robot(seen) != gr.robot("hopper")
        ours = next(j for j in pg.jobs(replace(full, worlds=(seen,))) if j.method == "sac")
        theirs = next(j for j in pg.jobs(replace(full, worlds=(base,))) if j.method == "sac")
        assert (ours.cfg, ours.tags) == (theirs.cfg, theirs.tags)


@pytest.mark.slow
def test_sac_on_a_seen_domain_trains_bit_for_bit_as_on_its_base_domain(tmp_path, monkeypatch):
    monkeypatch.setenv("MINDGAP_CACHE", str(tmp_path / "cache"))
    monkeypatch.setenv("MUJOCO_GL", "egl")
    out = tmp_path / "gym"
    args = ["reproduce", "gym", "--fast", "--quiet", "--worlds", "cheetah,cheetah-seen", "--out", str(out)]
    for key in ("cheetah/sac", "cheetah-seen/sac"):
        assert main([*args, "--job", key]) == 0
    base, seen = (json.loads(record_path(out, k).read_text()) for k in ("cheetah/sac", "cheetah-seen/sac"))
    assert gr.check_record(seen, base) == []
    assert len(base["curve"]) > 0 and base["final"] == seen["final"]
    assert (out / base["rollout"]).read_bytes() == (out / seen["rollout"]).read_bytes()

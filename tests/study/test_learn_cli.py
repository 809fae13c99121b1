"""``mindgap pebble|drlhp`` with the study: --preferences (offline) and --teacher study:STORE (live)."""

import json

from mindgap.cli import main


def test_pebble_learns_a_reward_offline_from_a_preferences_file(tmp_path):
    from study_helpers import study_file
    from test_offline import _answer_as_the_world_rewards

    from mindgap.study import export
    from mindgap.study.server import open_study

    config = study_file(tmp_path, "terrain-preference", participants=1)
    _, store, _ = open_study(config, tmp_path / "s.sqlite")
    _answer_as_the_world_rewards(store, pids=(1,))
    prefs = tmp_path / "preferences.json"
    prefs.write_text(export.preferences_json(store))
    out = tmp_path / "fit"
    assert main(["drlhp", "--world", "nav1", "--preferences", str(prefs), "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["records"] == 13 and summary["answers_agree_with_world_reward"] == 1.0
    assert (out / "reward.png").exists()


def test_a_live_teacher_needs_a_running_study(tmp_path, capsys):
    argv = ["pebble", "--world", "nav1", "--teacher", f"study:{tmp_path / 'none.sqlite'}", "--out", str(tmp_path)]
    assert main(argv) == 2
    assert "start the study first" in capsys.readouterr().err
    assert main(["pebble", "--world", "nav1", "--teacher", "oracle", "--out", str(tmp_path)]) == 2
    assert "--teacher must be biased, unbiased, true or study:STORE" in capsys.readouterr().err

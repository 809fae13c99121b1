"""Flags derived from a config's fields and their docstrings (mindgap.commands.config_flags)."""

import argparse

import pytest

from mindgap.algorithms import methods
from mindgap.algorithms.engine import Schedule
from mindgap.algorithms.pbrl import PbRLConfig, method_config
from mindgap.cli import _parser
from mindgap.commands.config_flags import add_config_flags, field_docs, given, with_flags


def _parse(cfg, argv, **kw):
    p = argparse.ArgumentParser(exit_on_error=False)
    add_config_flags(p, cfg, **kw)
    return p, p.parse_args(argv)


def test_field_docs_come_from_the_class_and_its_bases():
    docs = field_docs(PbRLConfig)
    assert docs["candidates"] == "Pairs drawn per query kept (score-based samplers)."  # PbRLConfig's own
    assert docs["total_steps"] == "Environment steps per seed."  # Schedule's
    assert set(docs) >= {f for f in Schedule.__dataclass_fields__}


def test_every_kind_of_field_parses_and_an_unset_flag_changes_nothing():
    cfg = method_config("pebble")
    _, args = _parse(cfg, [])
    assert given(args) == {} and with_flags(cfg, args) == cfg
    argv = ["--queries", "40", "--sac.lr", "1e-3", "--reward.hidden", "8,8", "--no-reset-critic", "--sac.alpha", "0.2"]
    _, args = _parse(cfg, argv)
    new = with_flags(cfg, args)
    assert (new.queries, new.sac.lr, new.reward.hidden, new.reset_critic, new.sac.alpha) == (
        40,
        1e-3,
        (8, 8),
        False,
        0.2,
    )
    _, args = _parse(cfg, ["--sac.alpha", "none"])
    assert with_flags(method_config("pebble", sac=cfg.sac.__class__(alpha=0.1)), args).sac.alpha is None
    with pytest.raises(argparse.ArgumentError):
        _parse(cfg, ["--queries", "many"])


def test_help_says_the_docstring_and_the_presets_default():
    p, _ = _parse(method_config("pebble"), [])
    text = " ".join(p.format_help().split())
    assert "--candidates CANDIDATES Pairs drawn per query kept (score-based samplers). (default: 10)" in text
    assert (
        "--reset-critic, --no-reset-critic Re-initialise the critic after pre-training (PEBBLE). (default: on)" in text
    )


def test_skip_and_only_leave_out_what_a_command_sets_itself():
    p, _ = _parse(method_config("sac"), [], skip=("sac.hidden",), only=("total_steps", "sac"))
    flags = {a.option_strings[0] for a in p._actions if a.option_strings}
    assert "--total-steps" in flags and "--sac.lr" in flags
    assert "--sac.hidden" not in flags and "--queries" not in flags


@pytest.mark.parametrize("command", ["sac", "pebble", "drlhp", "prefbias", "eps"])
def test_the_learner_commands_take_every_other_field_as_a_flag(command):
    args = _parser().parse_args([command, "--env", "d1", "--out", "x", "--sac.tau", "0.01", "--eval-episodes", "3"])
    assert given(args) == {"sac.tau": 0.01, "eval_episodes": 3}
    assert not hasattr(args, "cfg:total_steps")  # --steps sets it
    m = methods.get("drlhp-expectations" if command == "eps" else command)
    cfg = with_flags(m.preset("fast"), args)
    assert (cfg.sac.tau, cfg.eval_episodes) == (0.01, 3)

"""The ``mindgap`` command line.

mindgap reproduce table1 [--fast] [--seeds N] [--out DIR] [--fresh]
mindgap gerel --domain grid7 [--size N] [--belief B] [--seed S] [--out DIR]
mindgap gerel --domain grid7 --ratings FILE [--out DIR]
mindgap reproduce coffee [--fast] [--participants N] [--out DIR]
mindgap reproduce driving [--fast] [--seeds N] [--sleet S] [--traffic N] [--sanity expectation] [--importance A,B,C,D] [--answers-by rollout-behaviour|rollout|expectation|decisions] [--out DIR]
mindgap reproduce nav|priors|sampling|eps|lambda|gym [--fast] [--seeds N] [--worlds W,W | --env SPEC …] [--out DIR]
mindgap gerel --domain coffee [--robot R] [--ratings FILE] [--out DIR]
mindgap worlds list|show|plan …            (terrain worlds; see mindgap.commands.worlds)
mindgap design check WORLD …               (can a world show PrefBias's effect? see mindgap.commands.design)
mindgap sac|pebble|drlhp --world W --out DIR …   (preference-based RL; see mindgap.commands.learn)
mindgap NAME --world W --out DIR …   (a registered method with no command of its own; see mindgap.commands.method_command)
mindgap prefbias --world W --out DIR …   (PrefBias, Algorithm 2; see mindgap.commands.prefbias)
mindgap eps --world W --lam L --out DIR …   (EPS, Algorithm 3; see mindgap.commands.eps)
mindgap study serve|check|links|export|examples …  (user studies in the browser; see mindgap.commands.study)
mindgap report RUN_DIR … [--out DIR]       (one page of results beside the dissertation's; see mindgap.commands.report)
mindgap reproduce NAME --backend local|ray [--workers N] [--address ADDR]   (every job on workers, then assembled)
mindgap sweep SPEC.toml [--backend local|ray] …   (experiments and grids on workers or Ray; see mindgap.commands.sweep)
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys

from ._io import use_compilation_cache


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="mindgap", description="Learn what a person wants when they misjudge the robot.")
    sub = p.add_subparsers(dest="command", required=True)
    from .commands import design, eps, gerel, learn, method_command, prefbias, report, reproduce, study, sweep, worlds

    reproduce.add_parser(sub)
    worlds.add_parser(sub)
    design.add_parser(sub)
    learn.add_parsers(sub)
    prefbias.add_parser(sub)
    eps.add_parser(sub)
    study.add_parser(sub)
    report.add_parser(sub)
    sweep.add_parser(sub)
    gerel.add_parser(sub)
    method_command.add_parsers(sub, taken=COMMANDS)  # a registered method with no command of its own
    return p


COMMANDS = {
    "reproduce": "reproduce",
    "worlds": "worlds",
    "study": "study",
    "report": "report",
    "sweep": "sweep",
    "design": "design",
    "sac": "learn",
    "pebble": "learn",
    "drlhp": "learn",
    "prefbias": "prefbias",
    "eps": "eps",
    "gerel": "gerel",
}
"""Each subcommand's module in :mod:`mindgap.commands` (imported when it runs)."""


METHODS_VARIABLE = "MINDGAP_METHODS"
"""Files (``path.py``) or modules, comma-separated, imported before the commands are built: each
registers methods of its own (:func:`mindgap.algorithms.methods.register`), which then have a command."""


def _load_methods() -> None:
    from .envs.resolve import import_module

    for target in os.environ.get(METHODS_VARIABLE, "").split(","):
        if target.strip():
            import_module(target.strip())


def main(argv: list[str] | None = None) -> int:
    try:
        _load_methods()
    except ValueError as e:
        print(f"mindgap: error: {METHODS_VARIABLE}: {e}", file=sys.stderr)
        return 2
    args = _parser().parse_args(argv)
    use_compilation_cache()
    try:
        module = importlib.import_module(f"mindgap.commands.{COMMANDS.get(args.command, 'method_command')}")
        return module.run(args)
    except (ValueError, RuntimeError, FloatingPointError) as e:
        print(f"mindgap: error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())

"""``mindgap study serve|check|links|export|examples``: run a user study in a browser (docs/study.md).

mindgap study examples                                   # list the example study files
mindgap study examples coffee-rating --out study.yaml    # copy one
mindgap study check --config study.yaml                  # parse it, build its items
mindgap study serve --config study.yaml [--db FILE] [--host 127.0.0.1] [--port 8000] [--admin-token T]
                    [--public-url https://study.example.org]
mindgap study links --db FILE [--base http://host:port]  # the participants' personal links
mindgap study export --db FILE --out DIR [--partial]     # ratings.csv or preferences.json, answers.csv/json
mindgap study driving [--answers answers.json] [--ratings ratings.csv] [--out summary.json]   # §4.4.2's numbers
"""

from __future__ import annotations

import argparse
from importlib import resources
from pathlib import Path


def add_parser(sub) -> None:
    p = sub.add_parser("study", help="run a user study in the browser (rating, preference, expectation)")
    ss = p.add_subparsers(dest="study_command", required=True)
    s = ss.add_parser("serve", help="serve a study file's participant pages and dashboard")
    s.add_argument("--config", type=Path, required=True, help="the study file (YAML)")
    s.add_argument("--db", type=Path, help="the SQLite store (default NAME.sqlite; reruns continue it)")
    s.add_argument("--host", default="127.0.0.1", help="address to bind (default 127.0.0.1: this machine only)")
    s.add_argument("--port", type=int, default=8000, help="port (default 8000)")
    s.add_argument(
        "--admin-token", help="dashboard token (default: $MINDGAP_STUDY_ADMIN_TOKEN, or made once per store)"
    )
    s.add_argument(
        "--public-url",
        help="the server's address as participants reach it, for the dashboard's links "
        "(default: http://HOST:PORT it was started on)",
    )
    s.add_argument("--quiet", action="store_true", help="no request log (tokens in it are masked)")
    c = ss.add_parser("check", help="parse a study file and build its items")
    c.add_argument("--config", type=Path, required=True)
    ln = ss.add_parser("links", help="print the participants' personal links")
    ln.add_argument("--db", type=Path, required=True)
    ln.add_argument("--base", default="http://127.0.0.1:8000", help="the server's address as participants reach it")
    e = ss.add_parser("export", help="write the answers in the files the fitting commands read")
    e.add_argument("--db", type=Path, required=True)
    e.add_argument(
        "--out", type=Path, required=True, help="folder for ratings.csv or preferences.json, answers.csv/json"
    )
    e.add_argument("--partial", action="store_true", help="also export participants who did not finish")
    d = ss.add_parser("driving", help="the driving study's numbers from its exports (r_A's importances, Table 5)")
    d.add_argument("--answers", type=Path, help="the training phase's answers.json: importances, bias question")
    d.add_argument("--ratings", type=Path, help="the testing phase's ratings.csv: each method's average rating")
    d.add_argument("--out", type=Path, help="also write the numbers as JSON here")
    x = ss.add_parser("examples", help="list the example study files, or copy one")
    x.add_argument("name", nargs="?", help="an example's name")
    x.add_argument("--out", type=Path, help="where to copy it (default: print it)")


def _examples() -> dict[str, object]:
    folder = resources.files("mindgap.study") / "examples"
    return {f.name.removesuffix(".yaml"): f for f in folder.iterdir() if f.name.endswith(".yaml")}


def run(args: argparse.Namespace) -> int:
    cmd = args.study_command
    if cmd == "examples":
        ex = _examples()
        if not args.name:
            for name in sorted(ex):
                first = ex[name].read_text().splitlines()[0].lstrip("# ")
                print(f"{name:<22} {first}")
            return 0
        if args.name not in ex:
            raise ValueError(f"no example {args.name!r}: choose from {', '.join(sorted(ex))}")
        text = ex[args.name].read_text()
        if args.out:
            args.out.write_text(text)
            print(f"wrote {args.out}")
        else:
            print(text, end="")
        return 0
    if cmd == "check":
        from ..study.config import load_study
        from ..study.items import build_items

        study = load_study(args.config)
        items = build_items(study)
        sanity = [it.id for it in items if it.sanity]
        what = f"{len(items)} items"
        if study.live:
            what = "live queries from a training run" + (f" after {len(items)} fixed items" if items else "")
        print(f"study {study.name!r}: {study.protocol}, domain {study.domain['name']}, {what}")
        print(
            f"  {study.participants} participants, {len(study.questionnaire)} questions, sanity items: {sanity or 'none'}"
        )
        return 0
    if cmd == "driving":
        return _driving(args)
    if cmd == "serve":
        if not 0 < args.port < 65536:
            raise ValueError(f"--port must be 1..65535, got {args.port}")
        from ..study.server import serve

        serve(
            args.config, args.db, args.host, args.port, args.admin_token, quiet=args.quiet, public_url=args.public_url
        )
        return 0
    from ..study.store import Store

    if not args.db.is_file():
        raise ValueError(f"no study store {args.db}")
    store = Store(args.db)
    if cmd == "links":
        base = args.base.rstrip("/")
        for p in store.participants():
            print(f"{p['label']}\t{p['condition'] or '-'}\t{base}/p/{p['token']}")
        return 0
    from ..study.export import export_all

    for path in export_all(store, args.out, partial=args.partial):
        print(f"wrote {path}")
    return 0


def _driving(args: argparse.Namespace) -> int:
    """What the driving study's exports give (§4.4.2): r_A's importances and the bias count, Table 5's ratings."""
    import json

    from .._io import atomic_write
    from ..study.driving import testing_summary, training_summary

    if not args.answers and not args.ratings:
        raise ValueError(
            "give --answers (the training phase's answers.json) and/or --ratings (the testing phase's ratings.csv)"
        )
    out = {}
    for flag in ("answers", "ratings"):
        path = getattr(args, flag)
        if path is not None and not path.is_file():
            raise ValueError(f"--{flag}: no file {path}")
    if args.answers:
        t = out["training"] = training_summary(args.answers)
        imp = ", ".join(f"{k} {v:.2f}" for k, v in t["importance"].items())
        print(f"training phase: {t['valid']} valid participants of {t['participants']}; importance (1-5): {imp}")
        if t["bias_effective"] is not None:
            print(
                f"  bias question: {t['bias_effective']} of {t['bias_answered']} expect braking to work on sleet (the study: 12 of 14)"
            )
        print(f"  r_A from these answers: {t['reproduce']}")
    if args.ratings:
        t = out["testing"] = testing_summary(args.ratings)
        print(
            f"testing phase (Table 5): {t['raters']} valid raters"
            + (f", dropped {', '.join(t['dropped'])}" if t["dropped"] else "")
        )
        for m, r in t["methods"].items():
            print(f"  {m}: average rating {r['rating_mean']:.2f} ± {r['rating_std']:.2f} ({r['ratings']} ratings)")
    if args.out:
        atomic_write(args.out, json.dumps(out, indent=2))
        print(f"wrote {args.out}")
    return 0

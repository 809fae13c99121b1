"""Opening a study (file + store) and serving it with uvicorn."""

from __future__ import annotations

import copy
import logging
import os
import re
import shutil
from pathlib import Path

from .config import Study, load_study
from .items import build_items
from .render import Renderer
from .store import Store

ADMIN_ENV = "MINDGAP_STUDY_ADMIN_TOKEN"


_LINK = re.compile(r"(/p/)[^/?#\s]+")
_TOKEN = re.compile(r"([?&]token=)[^&#\s]*")


def redact(text: str) -> str:
    """``text`` with participant links (``/p/TOKEN``) and ``token=`` query values masked."""
    return _TOKEN.sub(r"\1***", _LINK.sub(r"\1***", text))


class RedactTokens(logging.Filter):
    """Masks the tokens in uvicorn's access log: a participant's link is their password."""

    def filter(self, record: logging.LogRecord) -> bool:
        if isinstance(record.args, tuple):
            record.args = tuple(redact(a) if isinstance(a, str) else a for a in record.args)
        record.msg = redact(str(record.msg))
        return True


def log_config() -> dict:
    """uvicorn's logging configuration with :class:`RedactTokens` on the access log."""
    from uvicorn.config import LOGGING_CONFIG

    config = copy.deepcopy(LOGGING_CONFIG)
    config.setdefault("filters", {})["redact"] = {"()": RedactTokens}
    config["handlers"]["access"].setdefault("filters", []).append("redact")
    return config


def default_db(study: Study) -> Path:
    return Path(f"{study.name}.sqlite")


def open_study(config, db=None, admin_token: str | None = None) -> tuple[Study, Store, Renderer]:
    """Read the study file, open (or create) its store, and bind them.

    On first use the items are built and stored and the study's participant links are
    created, and pictures left in ``<db>.media`` by an earlier store of that name are
    removed; later the store must belong to the same study file.
    """
    study = load_study(config)
    db = Path(db) if db else default_db(study)
    db.parent.mkdir(parents=True, exist_ok=True)
    store = Store(db)
    if store.meta("fingerprint") is None:
        items = [it.as_dict() for it in build_items(study)]
    else:
        items = []
    media = db.with_name(db.name + ".media")
    if store.bind_study(study, items, admin_token or os.environ.get(ADMIN_ENV) or None) and media.is_dir():
        shutil.rmtree(media)
    return study, store, Renderer(study, media)


def serve(
    config,
    db=None,
    host: str = "127.0.0.1",
    port: int = 8000,
    admin_token: str | None = None,
    quiet=False,
    public_url: str | None = None,
):
    """Run the study server until interrupted (binds ``host``, by default only this machine).

    ``public_url`` is the address participants reach the server at (behind a proxy, or a
    name for this machine): the dashboard's links start with it. By default it is the
    address the server was started on.
    """
    import uvicorn

    from .app import create_app, public_base

    shown = "127.0.0.1" if host in ("0.0.0.0", "::") else f"[{host}]" if ":" in host else host
    base = public_base(public_url or f"http://{shown}:{port}")
    study, store, renderer = open_study(config, db, admin_token)
    app = create_app(study, store, renderer, public_url=base)
    print(f"study {study.name!r} ({study.protocol}) with store {store.path}")
    print(f"dashboard: {base}/admin?token={store.meta('admin_token')}")
    print(f"{len(store.participants())} participant links on the dashboard (mindgap study links --db {store.path})")
    uvicorn.run(
        app,
        host=host,
        port=port,
        log_level="warning" if quiet else "info",
        access_log=not quiet,
        log_config=log_config(),
    )

"""Opening a study (file + store) and serving it with uvicorn."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

from .config import Study, load_study
from .items import build_items
from .render import Renderer
from .store import Store

ADMIN_ENV = "MINDGAP_STUDY_ADMIN_TOKEN"


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


def serve(config, db=None, host: str = "127.0.0.1", port: int = 8000, admin_token: str | None = None, quiet=False):
    """Run the study server until interrupted (binds ``host``, by default only this machine)."""
    import uvicorn

    from .app import create_app

    study, store, renderer = open_study(config, db, admin_token)
    app = create_app(study, store, renderer)
    shown = "127.0.0.1" if host in ("0.0.0.0", "::") else host
    base = f"http://{shown}:{port}"
    print(f"study {study.name!r} ({study.protocol}) with store {store.path}")
    print(f"dashboard: {base}/admin?token={store.meta('admin_token')}")
    print(f"{len(store.participants())} participant links on the dashboard (mindgap study links --db {store.path})")
    uvicorn.run(app, host=host, port=port, log_level="warning" if quiet else "info", access_log=not quiet)

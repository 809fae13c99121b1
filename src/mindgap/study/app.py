"""The study web app: participant pages, the researcher's dashboard and exports.

The framework is FastAPI (routing, forms, a thread pool for the blocking store) with
Jinja2 templates rendered on the server; the only JavaScript shows the slider's value
and holds the submit button until the slider was moved and the minimum time is over.
What is ours is the study logic:

* **Flow** (dissertation's MTurk studies, Figs. 9–11, 32–33): personal link → consent →
  instructions → questionnaire → one item per page → completion code. Every step is a
  POST that redirects back to ``/p/{token}`` (post/redirect/get), and that page is
  computed from the store, so a reload or a later visit continues where it stopped.
* **Access**: a participant is their unguessable link (``secrets.token_urlsafe``); items
  and pictures are served only to a participant they were given to. The dashboard and
  exports need the admin token (``Authorization: Bearer``, ``?token=`` which sets a
  SameSite=Strict cookie, or that cookie).
* **Forgery**: every form carries an HMAC of the participant (or admin) scope under a
  per-store secret, checked on POST; cross-site POSTs (``Origin`` of another host,
  ``Sec-Fetch-Site: cross-site``) are refused before that.
* **Bad input** gets a page saying what was wrong with a 4xx status: an unknown link
  (404, checked before the form is read), a form over 64 KiB (413), a wrong form token
  (403), an unknown item (404), an item out of order (409).
* **A refused answer** (no rating: the slider starts without a value and must be moved;
  a rating off the scale or its steps; an unknown choice; an answer faster than the
  study's minimum time) redirects back to the item (303, ``X-Answer: refused``), whose
  page says why and keeps the chosen value, so Back and reload never resend the form. A
  consent form without a choice and a questionnaire with a question unanswered are
  refused the same way, the answers given kept.
* **Live queries** gone while their page was open (withdrawn by the run, or answered by
  someone who was given it after its lease ran out) redirect to the participant's current
  page with a one-line notice (``?notice=closed|taken``), never to an error page.
* **Behind a proxy**: every address a page or redirect names starts with the public URL's
  path (``/lab``), and requests under that path are served too.
"""

from __future__ import annotations

from importlib import resources
from urllib.parse import urlsplit

from fastapi import FastAPI, Request
from fastapi.responses import PlainTextResponse
from fastapi.staticfiles import StaticFiles
from fastapi.templating import Jinja2Templates

from .config import Study
from .participants import participant_routes
from .render import Renderer
from .researcher import COOKIE, researcher_routes
from .site import Site
from .store import Store
from .web import HTTPError, StripPrefix, paragraphs, public_base

__all__ = ["COOKIE", "create_app"]

CSP = (
    "default-src 'none'; img-src 'self'; style-src 'self'; script-src 'self'; form-action 'self'; "
    "frame-ancestors 'none'; base-uri 'none'"
)


def create_app(
    study: Study,
    store: Store,
    renderer: Renderer,
    *,
    public_url: str = "http://127.0.0.1:8000",
    live_lease: float = 120.0,
) -> FastAPI:
    """The app for one study and its store (the store must be bound to the study).

    ``public_url`` is the server's address as participants reach it: the dashboard's
    links are built from it, never from a request's ``Host`` header, and every address
    the pages and redirects name starts with its path (``/lab`` for ``https://host/lab``),
    so the app works behind a reverse proxy at that path. The participants' routes are
    :mod:`~.participants`, the researcher's :mod:`~.researcher`.
    """
    public = public_base(public_url)
    public_host = urlsplit(public).netloc
    pkg = resources.files("mindgap.study")
    templates = Jinja2Templates(directory=str(pkg / "templates"))
    templates.env.filters["paragraphs"] = paragraphs
    site = Site(
        study, store, renderer, templates, public, store.meta("secret").encode(), {it["id"]: it for it in store.items()}
    )
    app = FastAPI(title=f"mindgap study {study.name}", docs_url=None, redoc_url=None, openapi_url=None)
    app.mount("/static", StaticFiles(directory=str(pkg / "static")), name="static")
    if site.root:
        app.add_middleware(StripPrefix, prefix=site.root)

    @app.exception_handler(HTTPError)
    async def _http_error(request: Request, e: HTTPError):
        return site.page(request, "message.html", e.status, title=e.title, text=e.text)

    @app.middleware("http")
    async def _guard(request: Request, call_next):
        if request.method == "POST":
            origin = request.headers.get("origin")
            if request.headers.get("sec-fetch-site") == "cross-site" or (
                origin
                and origin != "null"
                and urlsplit(origin).netloc not in (request.headers.get("host"), public_host)
            ):  # behind a proxy the Host header may name the upstream, the Origin the public URL
                return PlainTextResponse("cross-site form posts are refused", status_code=403)
        response = await call_next(request)
        response.headers.setdefault("Content-Security-Policy", CSP)
        response.headers["Referrer-Policy"] = "no-referrer"  # the personal link must not leak
        response.headers["X-Content-Type-Options"] = "nosniff"
        response.headers.setdefault("Cache-Control", "no-store")
        return response

    @app.get("/healthz")
    def healthz():
        return {"ok": True, "study": study.name}

    app.include_router(participant_routes(site, live_lease))
    app.include_router(researcher_routes(site))
    return app

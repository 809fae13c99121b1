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

import hashlib
import hmac
import json
import re
import secrets
import statistics
import time
from importlib import resources
from urllib.parse import urlencode, urlsplit

from fastapi import FastAPI, Request
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import FileResponse, HTMLResponse, JSONResponse, PlainTextResponse, RedirectResponse, Response
from fastapi.staticfiles import StaticFiles
from fastapi.templating import Jinja2Templates

from . import export
from .config import Study
from .render import Renderer
from .store import LIVE_PREFIX, Store
from .web import HTTPError, StripPrefix, likert, paragraphs, parse_rating, public_base, read_form, same_token

_SUBMISSION = re.compile(r"^[A-Za-z0-9_-]{8,64}$")
COOKIE = "mindgap_admin"
CHOICES = {"a": "A", "b": "B", "equal": "can't tell"}
NOTICES = {
    "closed": "That question was withdrawn before your answer arrived, so it was not recorded.",
    "taken": "Someone else answered that question first, so your answer was not recorded.",
    "more": "Please answer at least {n} questions before you finish.",
}
"""The one-line notices of a participant's page (``?notice=KEY``), each about their last form."""
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
    so the app works behind a reverse proxy at that path.
    """
    public = public_base(public_url)
    root = urlsplit(public).path  # "" or "/lab": the prefix of every address the app emits
    public_host = urlsplit(public).netloc
    pkg = resources.files("mindgap.study")
    templates = Jinja2Templates(directory=str(pkg / "templates"))
    templates.env.filters["paragraphs"] = paragraphs
    app = FastAPI(title=f"mindgap study {study.name}", docs_url=None, redoc_url=None, openapi_url=None)
    app.mount("/static", StaticFiles(directory=str(pkg / "static")), name="static")
    if root:
        app.add_middleware(StripPrefix, prefix=root)
    secret = store.meta("secret").encode()
    items = {it["id"]: it for it in store.items()}
    lo, hi, step = study.rating_scale

    def csrf(scope: str) -> str:
        return hmac.new(secret, scope.encode(), hashlib.sha256).hexdigest()

    def page(request: Request, name: str, status: int = 200, **ctx) -> Response:
        ctx.setdefault("study", study)
        ctx.setdefault("root", root)
        return templates.TemplateResponse(request, name, ctx, status_code=status)

    @app.exception_handler(HTTPError)
    async def _http_error(request: Request, e: HTTPError):
        return page(request, "message.html", e.status, title=e.title, text=e.text)

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

    # -- participants ---------------------------------------------------------------------
    def who(token: str):
        p = store.participant(token)
        if p is None:
            raise HTTPError(
                404, "Link not valid", "This study link is not valid. Please check the address you were given."
            )
        return p

    def check_csrf(form, token: str) -> None:
        if not same_token(str(form.get("csrf", "")), csrf("p:" + token)):
            raise HTTPError(403, "Form expired", "This form was not sent from your study page. Please reload the page.")

    def stage(p) -> str:
        if p["declined_at"]:
            return "declined"
        if p["completed_at"]:
            return "done"
        if not p["consent_at"]:
            return "consent"
        if not p["instructions_at"]:
            return "instructions"
        if study.questionnaire and not p["questionnaire_at"]:
            return "questionnaire"
        return "items"

    def current_item(p) -> str | None:
        """The participant's next item id, or None when all are answered (or no live query waits)."""
        done = store.answered_ids(p["id"])
        fixed = next((i for i in json.loads(p["item_order"]) if i not in done), None)
        if fixed is not None or not study.live:  # a live study's fixed items (driving's) come first
            return fixed
        qid = store.claim_live(p["id"], live_lease)
        return None if qid is None else f"{LIVE_PREFIX}{qid}"

    def item_of(p, item_id: str) -> dict:
        """The item ``item_id`` if it was given to participant ``p`` (else 404)."""
        if item_id.startswith(LIVE_PREFIX) and study.live:
            try:
                q = store.live_query(int(item_id[len(LIVE_PREFIX) :]))
            except ValueError:
                q = None
            # shown to them once, it stays theirs to answer even when its lease passed to another
            if q is not None and (q["claimed_by"] == p["id"] or store.shown_at(p["id"], item_id) is not None):
                return {"id": item_id, "kind": "pair", "data": json.loads(q["data"])}
        elif item_id in json.loads(p["item_order"]):
            return items[item_id]
        raise HTTPError(404, "Unknown item", f"There is no item {item_id!r} in your study.")

    def refusal(code: str) -> str:
        """What a refused answer's page says (``code`` comes back in the page's address)."""
        return {
            "missing": f"Please move the slider to give your rating (from {lo:g} to {hi:g}).",
            "rating": f"The rating must be a number from {lo:g} to {hi:g} in steps of {step:g}.",
            "choice": "Please choose A, B or can't tell.",
            "too-fast": f"Please take at least {study.min_seconds:g} seconds to look at each item.",
        }[code]

    def show(
        request: Request, p, status: int = 200, error: str = "", kept: dict | None = None, notice: str = ""
    ) -> Response:
        """The participant's current page; ``kept`` is a refused answer to show again (code, item, value),
        ``notice`` one line about what happened to their last form (a withdrawn question)."""
        s = stage(p)
        token = p["token"]
        ctx = dict(token=token, csrf=csrf("p:" + token), error=error, notice=notice)
        if s in ("declined", "consent", "instructions", "questionnaire"):
            if kept and kept["code"] == s:  # a refused consent or questionnaire: why, and the answers given
                ctx["error"] = kept["error"]
                ctx["given"] = kept["given"]
            return page(request, f"{s}.html", status, **ctx)
        if s == "done":
            return page(request, "done.html", status, code=p["completion_code"], **ctx)
        item_id = current_item(p)
        if item_id is None:
            if study.live:
                done = store.answered_ids(p["id"])
                live = sum(i.startswith(LIVE_PREFIX) for i in done)
                return page(request, "wait.html", status, answered=len(done), live=live, **ctx)
            store.mark(p["id"], "completed")
            return show(request, store.participant(token), status)
        item = item_of(p, item_id)
        shown = store.first_view(p["id"], item_id)
        wait = max(0.0, study.min_seconds - (time.time() - shown))
        order = json.loads(p["item_order"])
        rating = chosen = None
        if kept and kept.get("item") == item_id:  # the refused answer to this very item: its message and value
            ctx["error"] = refusal(kept["code"])
            value = parse_rating(kept.get("rating") or "", lo, hi, step)
            rating = None if value is None else f"{value:g}"
            chosen = kept.get("choice") if kept.get("choice") in CHOICES else None
        ctx.update(
            item=item,
            number=(order.index(item_id) + 1) if item_id in order else len(store.answered_ids(p["id"])) + 1,
            total=None if study.live else len(order) or None,
            submission=secrets.token_urlsafe(12),
            wait=round(wait, 1),
            scale=(lo, hi, step),
            rating=rating,
            chosen=chosen,
            choices=CHOICES,
            parts=renderer.parts(item),
        )
        return page(request, "item.html", status, **ctx)

    @app.get("/healthz")
    def healthz():
        return {"ok": True, "study": study.name}

    @app.get("/p/{token}", response_class=HTMLResponse)
    def participant_page(request: Request, token: str):
        q = request.query_params
        kept = None
        if q.get("refused") in ("missing", "rating", "choice", "too-fast"):
            kept = {"code": q["refused"], "item": q.get("item"), "rating": q.get("rating"), "choice": q.get("choice")}
        elif q.get("refused") == "consent":
            kept = {"code": "consent", "error": "Please say whether you agree to take part.", "given": {}}
        elif q.get("refused") == "questionnaire":
            given = {x.id: v for x in study.questionnaire if (v := likert(q.get(x.id, ""), x.scale)) is not None}
            first = next((k for k, x in enumerate(study.questionnaire) if x.id not in given), None)
            error = "Please answer every question."
            if first is not None:  # named by its place on the page: its id is the researcher's label
                lo_, hi_ = study.questionnaire[first].scale
                error = f"Please answer every question (question {first + 1}: choose {lo_}–{hi_})."
            kept = {"code": "questionnaire", "error": error, "given": given}
        notice = NOTICES.get(q.get("notice", ""), "").format(n=study.min_live_answers)
        return show(request, who(token), kept=kept, notice=notice)

    async def form_of(request: Request, token: str):
        """The participant (404 for an unknown link, before the body is read) and their checked form."""
        p = await run_in_threadpool(who, token)
        form = await read_form(request)
        check_csrf(form, token)
        return form, p

    def back(token: str, outcome: str = "", notice: str = "") -> Response:
        """Post/redirect/get to the participant's current page, with a one-line ``notice`` (a key of NOTICES)."""
        r = RedirectResponse(f"{root}/p/{token}" + (f"?notice={notice}" if notice else ""), status_code=303)
        if outcome:
            r.headers["X-Answer"] = outcome
        return r

    def refuse(token: str, item_id: str, code: str, **value: str) -> Response:
        """Post/redirect/get for a refused answer: back to the item, whose page says why and keeps the value."""
        query = urlencode({"item": item_id, "refused": code, **{k: v for k, v in value.items() if v}})
        r = RedirectResponse(f"{root}/p/{token}?{query}", status_code=303)
        r.headers["X-Answer"] = "refused"
        return r

    def refused_page(token: str, code: str, **given: str) -> Response:
        """Post/redirect/get for a refused consent or questionnaire form: its page again, saying why."""
        r = RedirectResponse(f"{root}/p/{token}?{urlencode({'refused': code, **given})}", status_code=303)
        r.headers["X-Answer"] = "refused"
        return r

    @app.post("/p/{token}/consent")
    async def consent(request: Request, token: str):
        form, p = await form_of(request, token)
        if form.get("agree") == "yes":
            await run_in_threadpool(store.mark, p["id"], "consent")
        elif form.get("agree") == "no":
            await run_in_threadpool(store.mark, p["id"], "declined")
        else:  # post/redirect/get: the consent page again, saying why
            return refused_page(token, "consent")
        return back(token)

    @app.post("/p/{token}/instructions")
    async def instructions(request: Request, token: str):
        _, p = await form_of(request, token)
        if not p["consent_at"]:
            raise HTTPError(409, "Consent first", "Please read and accept the consent form first.")
        await run_in_threadpool(store.mark, p["id"], "instructions")
        return back(token)

    @app.post("/p/{token}/questionnaire")
    async def questionnaire(request: Request, token: str):
        form, p = await form_of(request, token)
        if stage(p) != "questionnaire":
            return back(token)
        answers = {q.id: v for q in study.questionnaire if (v := likert(str(form.get(q.id, "")), q.scale)) is not None}
        if len(answers) < len(study.questionnaire):  # post/redirect/get, keeping the answers given
            return refused_page(token, "questionnaire", **{k: str(v) for k, v in answers.items()})
        await run_in_threadpool(store.save_questionnaire, p["id"], answers)
        return back(token)

    @app.post("/p/{token}/answer")
    async def answer(request: Request, token: str):
        form, p = await form_of(request, token)
        return await run_in_threadpool(_answer, request, p, form)

    def _answer(request: Request, p, form) -> Response:
        token = p["token"]
        if stage(p) != "items":
            if stage(p) in ("done", "declined"):  # e.g. a form left open in another tab
                return back(token, "answered" if stage(p) == "done" else "")
            raise HTTPError(409, "Not yet", "Please finish the consent form, instructions and questionnaire first.")
        submission = str(form.get("submission_id", ""))
        if not _SUBMISSION.match(submission):
            raise HTTPError(400, "Bad form", "The answer form is missing its submission id. Please reload the page.")
        item_id = str(form.get("item_id", ""))
        item = item_of(p, item_id)
        if item["kind"] == "demo":
            raw = form.get("rating", "")
            if raw == "":  # the slider was never moved: an untouched midpoint is no answer
                return refuse(token, item_id, "missing")
            value = parse_rating(raw, lo, hi, step)
            if value is None:
                return refuse(token, item_id, "rating")
            choice = None
        else:
            choice = form.get("choice", "")
            if choice not in CHOICES:
                return refuse(token, item_id, "choice")
            value = {"a": 1.0, "b": 0.0, "equal": 0.5}[choice]
        order = None if item_id.startswith(LIVE_PREFIX) else json.loads(p["item_order"])
        outcome = store.record_answer(
            p["id"], item_id, value, choice, submission, order=order, min_seconds=study.min_seconds
        )
        if outcome == "out-of-order":
            raise HTTPError(409, "Out of order", "Please answer the items in the order they are shown.")
        if outcome == "not-shown":
            raise HTTPError(409, "Not shown", "This item has not been shown to you yet.")
        if outcome == "too-fast":
            return refuse(token, item_id, "too-fast", rating=form.get("rating", ""), choice=choice or "")
        if outcome == "conflict":
            raise HTTPError(409, "Bad form", "This form was already used for another answer. Please reload the page.")
        if outcome in ("closed", "taken"):  # a live query gone meanwhile: on to the next page, saying so
            return back(token, outcome, notice=outcome)
        if outcome == "not-yours":
            raise HTTPError(404, "Unknown item", f"There is no item {item_id!r} in your study.")
        return back(token, outcome)

    @app.post("/p/{token}/finish")
    async def finish(request: Request, token: str):
        _, p = await form_of(request, token)
        if stage(p) == "items" and study.live:
            done = await run_in_threadpool(store.answered_ids, p["id"])
            if sum(i.startswith(LIVE_PREFIX) for i in done) < study.min_live_answers:
                return back(token, "refused", notice="more")
            await run_in_threadpool(store.mark, p["id"], "completed")
        return back(token)

    @app.get("/p/{token}/media/{item_id}/{part}")
    def media(token: str, item_id: str, part: str):
        p = who(token)
        item = item_of(p, item_id)
        if part not in dict(renderer.parts(item)):
            raise HTTPError(404, "Unknown picture", f"Item {item_id!r} has no picture {part!r}.")
        path = renderer.path(item, part, p["condition"])
        return FileResponse(path, headers={"Cache-Control": "private, max-age=3600"})

    # -- researcher -----------------------------------------------------------------------
    admin_token = store.meta("admin_token")

    def is_admin(request: Request) -> bool:
        given = request.headers.get("authorization", "").removeprefix("Bearer ").strip()
        given = given or request.cookies.get(COOKIE, "") or request.query_params.get("token", "")
        return bool(given) and same_token(given, admin_token)

    def require_admin(request: Request) -> None:
        if not is_admin(request):
            raise HTTPError(401, "Researchers only", "This page needs the study's admin token.")

    @app.get("/admin", response_class=HTMLResponse)
    def dashboard(request: Request):
        require_admin(request)
        if "token" in request.query_params:  # keep the token out of the address bar and history
            r = RedirectResponse(f"{root}/admin", status_code=303)
            r.set_cookie(COOKIE, admin_token, httponly=True, samesite="strict", secure=public.startswith("https:"))
            return r
        return page(request, "admin.html", **dashboard_data())

    def dashboard_data() -> dict:
        answers = store.answers()
        failed = export.sanity_failures(items, answers)
        by_person: dict[str, list] = {}
        by_item: dict[str, list] = {}
        for a in answers:
            by_person.setdefault(a["participant"], []).append(a)
            by_item.setdefault(a["item_id"], []).append(a)
        people = []
        for p in store.participants():
            mine = by_person.get(p["label"], [])
            live = sum(a["item_id"].startswith(LIVE_PREFIX) for a in mine)
            secs = [a["seconds"] for a in mine if a["seconds"] is not None]
            people.append(
                dict(
                    label=p["label"],
                    link=f"{public}/p/{p['token']}",
                    condition=p["condition"],
                    stage=stage(p),
                    answered=len(mine),  # fixed items and live queries: fixed ones of total, and live ones
                    total=len(json.loads(p["item_order"])) or None,
                    live_answered=live,
                    failed=failed.get(p["label"], []),
                    median_seconds=statistics.median(secs) if secs else None,
                    code=p["completion_code"] if p["completed_at"] else "",
                )
            )
        rows = []
        for item_id in list(items) + sorted(set(by_item) - set(items)):
            got = by_item.get(item_id, [])
            secs = [a["seconds"] for a in got if a["seconds"] is not None]
            summary = (
                f"mean {statistics.fmean(a['value'] for a in got):.2f}"
                if got and study.protocol == "rating"
                else " ".join(f"{CHOICES[c]}: {sum(a['choice'] == c for a in got)}" for c in CHOICES)
                if got
                else ""
            )
            rows.append(
                dict(
                    id=item_id,
                    answers=len(got),
                    summary=summary,
                    mean_seconds=statistics.fmean(secs) if secs else None,
                    median_seconds=statistics.median(secs) if secs else None,
                    sanity=(items.get(item_id) or {}).get("sanity"),
                    failures=sum(item_id in f for f in failed.values()),
                )
            )
        return dict(
            people=people,
            items=rows,
            n_answers=len(answers),
            n_done=sum(p["stage"] == "done" for p in people),
            n_failed=sum(bool(p["failed"]) for p in people),
            live=store.live_counts() if study.live else None,
            admin_csrf=csrf("admin"),
            fitting="ratings.csv" if study.protocol == "rating" else "preferences.json",
        )

    @app.get("/admin/api/status")
    def status(request: Request):
        require_admin(request)
        d = dashboard_data()
        return JSONResponse({k: d[k] for k in ("people", "items", "n_answers", "n_done", "n_failed", "live")})

    @app.get("/admin/export/{name}")
    def export_file(request: Request, name: str, partial: bool = False):
        require_admin(request)
        makers = {
            "ratings.csv": lambda: export.ratings_csv(store, partial),
            "preferences.json": lambda: export.preferences_json(store, partial),
            "answers.csv": lambda: export.answers_csv(store),
            "answers.json": lambda: export.answers_json(store),
        }
        if name not in makers:
            raise HTTPError(404, "Unknown export", f"Exports: {', '.join(makers)}.")
        try:
            body = makers[name]()
        except ValueError as e:
            raise HTTPError(409, "Not for this study", str(e)) from None
        kind = "text/csv" if name.endswith(".csv") else "application/json"
        return Response(body, media_type=kind, headers={"Content-Disposition": f'attachment; filename="{name}"'})

    @app.post("/admin/participants")
    async def add_participants(request: Request):
        require_admin(request)
        form = await read_form(request)
        if not same_token(str(form.get("csrf", "")), csrf("admin")):
            raise HTTPError(403, "Form expired", "This form was not sent from the dashboard. Please reload it.")
        try:
            n = int(str(form.get("count", "")))
        except ValueError:
            n = 0
        if not 1 <= n <= 1000:
            raise HTTPError(422, "Bad count", "Add between 1 and 1000 participants at a time.")
        await run_in_threadpool(store.add_participants, study, n)
        return RedirectResponse(f"{root}/admin", status_code=303)

    return app

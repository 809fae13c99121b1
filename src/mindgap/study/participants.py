"""The participants' pages of the study app: their link, consent, instructions, questionnaire, the
items one per page, live queries and pictures (the flow and its refusals: :mod:`~.app`)."""

from __future__ import annotations

import json
import re
import secrets
import time
from urllib.parse import urlencode

from fastapi import APIRouter, Request
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import FileResponse, HTMLResponse, RedirectResponse, Response

from .site import Site
from .store import LIVE_PREFIX
from .web import HTTPError, likert, parse_rating, read_form, same_token

_SUBMISSION = re.compile(r"^[A-Za-z0-9_-]{8,64}$")
COOKIE = "mindgap_admin"
CHOICES = {"a": "A", "b": "B", "equal": "can't tell"}
NOTICES = {
    "closed": "That question was withdrawn before your answer arrived, so it was not recorded.",
    "taken": "Someone else answered that question first, so your answer was not recorded.",
    "more": "Please answer at least {n} questions before you finish.",
}
"""The one-line notices of a participant's page (``?notice=KEY``), each about their last form."""


def participant_routes(site: Site, live_lease: float) -> APIRouter:
    """The participants' routes of ``site``; a live query's lease on a participant lasts ``live_lease`` seconds."""
    router = APIRouter()
    study, store, renderer, items, root = site.study, site.store, site.renderer, site.items, site.root
    csrf, page, stage = site.csrf, site.page, site.stage
    lo, hi, step = study.rating_scale

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

    @router.get("/p/{token}", response_class=HTMLResponse)
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

    @router.post("/p/{token}/consent")
    async def consent(request: Request, token: str):
        form, p = await form_of(request, token)
        if form.get("agree") == "yes":
            await run_in_threadpool(store.mark, p["id"], "consent")
        elif form.get("agree") == "no":
            await run_in_threadpool(store.mark, p["id"], "declined")
        else:  # post/redirect/get: the consent page again, saying why
            return refused_page(token, "consent")
        return back(token)

    @router.post("/p/{token}/instructions")
    async def instructions(request: Request, token: str):
        _, p = await form_of(request, token)
        if not p["consent_at"]:
            raise HTTPError(409, "Consent first", "Please read and accept the consent form first.")
        await run_in_threadpool(store.mark, p["id"], "instructions")
        return back(token)

    @router.post("/p/{token}/questionnaire")
    async def questionnaire(request: Request, token: str):
        form, p = await form_of(request, token)
        if stage(p) != "questionnaire":
            return back(token)
        answers = {q.id: v for q in study.questionnaire if (v := likert(str(form.get(q.id, "")), q.scale)) is not None}
        if len(answers) < len(study.questionnaire):  # post/redirect/get, keeping the answers given
            return refused_page(token, "questionnaire", **{k: str(v) for k, v in answers.items()})
        await run_in_threadpool(store.save_questionnaire, p["id"], answers)
        return back(token)

    @router.post("/p/{token}/answer")
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

    @router.post("/p/{token}/finish")
    async def finish(request: Request, token: str):
        _, p = await form_of(request, token)
        if stage(p) == "items" and study.live:
            done = await run_in_threadpool(store.answered_ids, p["id"])
            if sum(i.startswith(LIVE_PREFIX) for i in done) < study.min_live_answers:
                return back(token, "refused", notice="more")
            await run_in_threadpool(store.mark, p["id"], "completed")
        return back(token)

    @router.get("/p/{token}/media/{item_id}/{part}")
    def media(token: str, item_id: str, part: str):
        p = who(token)
        item = item_of(p, item_id)
        if part not in dict(renderer.parts(item)):
            raise HTTPError(404, "Unknown picture", f"Item {item_id!r} has no picture {part!r}.")
        path = renderer.path(item, part, p["condition"])
        return FileResponse(path, headers={"Cache-Control": "private, max-age=3600"})

    return router

"""The researcher's pages of the study app: the dashboard, its status API, the exports and adding
participants, all behind the study's admin token."""

from __future__ import annotations

import json
import statistics

from fastapi import APIRouter, Request
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import HTMLResponse, JSONResponse, RedirectResponse, Response

from . import export
from .participants import CHOICES
from .site import Site
from .store import LIVE_PREFIX
from .web import HTTPError, read_form, same_token

COOKIE = "mindgap_admin"


def researcher_routes(site: Site) -> APIRouter:
    """The researcher's routes of ``site``."""
    router = APIRouter()
    study, store, items, root = site.study, site.store, site.items, site.root
    csrf, page, stage = site.csrf, site.page, site.stage
    public = site.public

    admin_token = store.meta("admin_token")

    def is_admin(request: Request) -> bool:
        given = request.headers.get("authorization", "").removeprefix("Bearer ").strip()
        given = given or request.cookies.get(COOKIE, "") or request.query_params.get("token", "")
        return bool(given) and same_token(given, admin_token)

    def require_admin(request: Request) -> None:
        if not is_admin(request):
            raise HTTPError(401, "Researchers only", "This page needs the study's admin token.")

    @router.get("/admin", response_class=HTMLResponse)
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

    @router.get("/admin/api/status")
    def status(request: Request):
        require_admin(request)
        d = dashboard_data()
        return JSONResponse({k: d[k] for k in ("people", "items", "n_answers", "n_done", "n_failed", "live")})

    @router.get("/admin/export/{name}")
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

    @router.post("/admin/participants")
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

    return router

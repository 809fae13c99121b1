"""What every page of the study app shares: the study, its store and renderer, the address prefix,
the form tokens and the template renderer (:class:`Site`), and where a participant stands (:meth:`Site.stage`)."""

from __future__ import annotations

import hashlib
import hmac
from dataclasses import dataclass
from urllib.parse import urlsplit

from fastapi import Request
from fastapi.responses import Response
from fastapi.templating import Jinja2Templates

from .config import Study
from .render import Renderer
from .store import Store


@dataclass
class Site:
    """One study's app: what the participants' and the researcher's routes (:mod:`~.participants`,
    :mod:`~.researcher`) read."""

    study: Study
    store: Store
    renderer: Renderer
    templates: Jinja2Templates
    public: str
    """The public URL without a trailing slash (``https://host/lab``)."""
    secret: bytes
    """The store's secret, which the forms' tokens are HMACs under."""
    items: dict
    """The study's fixed items by id."""

    @property
    def root(self) -> str:
        """The path every address the app emits starts with: "" or "/lab"."""
        return urlsplit(self.public).path

    def csrf(self, scope: str) -> str:
        """The form token of ``scope`` (``p:TOKEN`` for a participant, ``admin``)."""
        return hmac.new(self.secret, scope.encode(), hashlib.sha256).hexdigest()

    def page(self, request: Request, name: str, status: int = 200, **ctx) -> Response:
        """The template ``name`` rendered with ``ctx`` (and the study and the address prefix)."""
        ctx.setdefault("study", self.study)
        ctx.setdefault("root", self.root)
        return self.templates.TemplateResponse(request, name, ctx, status_code=status)

    def stage(self, p) -> str:
        """Where participant ``p`` stands: declined, done, consent, instructions, questionnaire or items."""
        if p["declined_at"]:
            return "declined"
        if p["completed_at"]:
            return "done"
        if not p["consent_at"]:
            return "consent"
        if not p["instructions_at"]:
            return "instructions"
        if self.study.questionnaire and not p["questionnaire_at"]:
            return "questionnaire"
        return "items"

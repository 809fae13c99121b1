"""Request-level pieces of the study app: reading a form, checking tokens and answers, the public URL."""

from __future__ import annotations

import hmac
import re
from decimal import Decimal
from urllib.parse import parse_qsl, urlsplit

from fastapi import Request

MAX_FORM = 64 * 1024  # bytes: the largest form a page sends is well under 1 KiB
_PLAIN = re.compile(r"-?[0-9]{1,9}(\.[0-9]{1,9})?")


def same_token(given: str, expected: str) -> bool:
    """A constant-time comparison of a sent token with the expected one (any text: compared as UTF-8 bytes)."""
    return hmac.compare_digest(given.encode("utf-8", "surrogatepass"), expected.encode("utf-8", "surrogatepass"))


def likert(raw: str, scale: tuple[int, int]) -> int | None:
    """A questionnaire answer: an ASCII whole number on ``scale`` (``3``), None otherwise (``³``, ``99``)."""
    if not re.fullmatch(r"[0-9]{1,3}", raw) or not scale[0] <= int(raw) <= scale[1]:
        return None
    return int(raw)


class StripPrefix:
    """ASGI wrapper: a request under the public URL's path (``/lab/p/...``) is served as ``/p/...``.

    So the app works behind a proxy that strips the prefix and behind one that passes it on.
    """

    def __init__(self, app, prefix: str):
        self.app, self.prefix = app, prefix

    async def __call__(self, scope, receive, send):
        path = scope.get("path", "")
        if scope["type"] == "http" and self.prefix and path.startswith(self.prefix + "/"):
            rest = path[len(self.prefix) :]
            scope = dict(scope, path=rest, raw_path=rest.encode())
        await self.app(scope, receive, send)


class HTTPError(Exception):
    def __init__(self, status: int, title: str, text: str):
        self.status, self.title, self.text = status, title, text


async def read_form(request: Request) -> dict[str, str]:
    """The URL-encoded form of a POST, refused (413) when it is over :data:`MAX_FORM` bytes.

    A larger ``Content-Length`` is refused before any of the body is read, and a body
    without one (chunked) is read only up to the limit.
    """
    too_large = HTTPError(413, "Form too large", f"A study form is at most {MAX_FORM // 1024} KiB.")
    length = request.headers.get("content-length")
    if length is not None and (not length.isdigit() or int(length) > MAX_FORM):
        raise too_large
    kind = request.headers.get("content-type", "").split(";")[0].strip().lower()
    if kind != "application/x-www-form-urlencoded":
        raise HTTPError(415, "Not a form", "Answers are sent by the study page's forms.")
    body = bytearray()
    async for chunk in request.stream():
        body += chunk
        if len(body) > MAX_FORM:
            raise too_large
    try:
        return dict(parse_qsl(body.decode("utf-8"), keep_blank_values=True, max_num_fields=100))
    except (UnicodeDecodeError, ValueError):
        raise HTTPError(400, "Bad form", "This form could not be read. Please reload the page.") from None


def parse_rating(raw: str, lo: float, hi: float, step: float) -> float | None:
    """A rating written as a plain decimal in ``[lo, hi]`` on the grid ``lo + k·step``; None otherwise.

    Exact (decimal) arithmetic, so 6.5 is on a 0.5 grid and 0.3 on a 0.1 grid; ``1e1``,
    ``nan``, ``+6`` and other spellings a slider never sends are refused.
    """
    if not _PLAIN.fullmatch(raw):
        return None
    v = Decimal(raw)
    d_lo, d_hi, d_step = (Decimal(repr(float(x))) for x in (lo, hi, step))
    if not d_lo <= v <= d_hi or (v - d_lo) % d_step != 0:
        return None
    return float(v)


def paragraphs(text: str) -> list[str]:
    """Blank-line-separated paragraphs of a study text (escaped by the template)."""
    return [p.strip() for p in re.split(r"\n\s*\n", text or "") if p.strip()]


def public_base(url: str) -> str:
    """A server's public address (``https://host[:port][/path]``) without its trailing slash.

    Raises:
        ValueError: not an http(s) address with a host, or one with a query or fragment.
    """
    parts = urlsplit(url)
    if parts.scheme not in ("http", "https") or not parts.hostname or parts.query or parts.fragment:
        raise ValueError(f"the public address must look like https://study.example.org[/path], got {url!r}")
    return url.rstrip("/")

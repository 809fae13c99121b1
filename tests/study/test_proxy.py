"""A study served behind a reverse proxy at a path prefix (``--public-url http://HOST/lab``)."""

import http.client
import re
import threading
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

import httpx
import pytest
from study_helpers import ADMIN, Participant, Server, free_port, hidden, study_file

PREFIX = "/lab"
HOP = {"connection", "keep-alive", "transfer-encoding", "host", "content-length"}


class Proxy:
    """A small reverse proxy: ``/lab/...`` goes to the upstream as ``/...`` (the prefix stripped, the Host
    header rewritten to the upstream's, as nginx's ``proxy_pass http://upstream/;`` does); anything else 404."""

    def __init__(self, upstream_port: int):
        port = upstream_port

        class Handler(BaseHTTPRequestHandler):
            def log_message(self, *args):
                pass

            def _forward(self):
                if not self.path.startswith(PREFIX + "/"):
                    self.send_error(404, "not under the proxy's prefix")
                    return
                body = self.rfile.read(int(self.headers.get("content-length") or 0))
                headers = {k: v for k, v in self.headers.items() if k.lower() not in HOP}
                up = http.client.HTTPConnection("127.0.0.1", port, timeout=60)
                up.request(self.command, self.path[len(PREFIX) :], body=body or None, headers=headers)
                r = up.getresponse()
                data = r.read()
                self.send_response(r.status)
                for k, v in r.getheaders():
                    if k.lower() not in HOP:
                        self.send_header(k, v)
                self.send_header("Content-Length", str(len(data)))
                self.end_headers()
                self.wfile.write(data)
                up.close()

            do_GET = do_POST = _forward

        self.server = ThreadingHTTPServer(("127.0.0.1", free_port()), Handler)
        self.thread = threading.Thread(target=self.server.serve_forever, daemon=True)

    @property
    def base(self) -> str:
        return f"http://127.0.0.1:{self.server.server_address[1]}"

    def __enter__(self):
        self.thread.start()
        return self

    def __exit__(self, *exc):
        self.server.shutdown()
        self.server.server_close()


_URL = re.compile(r'(?:href|src|action)="([^"]*)"')


def _check_addresses(response: httpx.Response) -> None:
    """Every address the app sends (redirects, links, pictures, forms, stylesheet, script) is under the prefix."""
    if "location" in response.headers:
        assert response.headers["location"].startswith(PREFIX + "/"), response.headers["location"]
    if response.headers.get("content-type", "").startswith("text/html"):
        response.read()
        for url in _URL.findall(response.text):
            assert url.startswith(PREFIX + "/"), (response.url, url)


@pytest.fixture(scope="module")
def behind_proxy(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("proxy")
    config = study_file(tmp, "coffee-rating", participants=2, min_seconds=0)
    upstream = Server(config, tmp / "proxied.sqlite")
    with Proxy(upstream.port) as proxy:
        upstream.extra = ("--public-url", proxy.base + PREFIX)
        upstream.start()
        try:
            yield proxy, upstream
        finally:
            upstream.stop()


def test_a_participant_completes_a_study_through_a_proxy_at_a_path_prefix(behind_proxy):
    proxy, upstream = behind_proxy
    # a browser's form posts carry the Origin of the public address; the upstream sees another Host
    with httpx.Client(
        base_url=proxy.base, headers={"Origin": proxy.base}, event_hooks={"response": [_check_addresses]}
    ) as http:
        links = http.get(f"{PREFIX}/admin/api/status", headers={"Authorization": f"Bearer {ADMIN}"}).json()["people"]
        assert links[0]["link"].startswith(f"{proxy.base}{PREFIX}/p/")
        token = links[0]["link"].rsplit("/", 1)[1]
        first = http.get(f"{PREFIX}/p/{token}").text
        for asset in re.findall(r'(?:href|src)="([^"]*/static/[^"]*)"', first):
            assert http.get(asset).status_code == 200, asset  # the page is styled and scripted
        p = Participant(http, token, rate=lambda item: 0 if item == "sanity-random" else 6, prefix=PREFIX)
        pictures = 0
        while p.step():
            page = p.get()
            for src in re.findall(r'<img src="([^"]+)"', page)[:1]:
                assert http.get(src).status_code == 200, src
                pictures += 1
        assert pictures == 9 and len(p.acked) == 9 and re.fullmatch(r"[0-9A-F]{8}", p.code)
        r = http.get(f"{PREFIX}/admin?token={ADMIN}", follow_redirects=False)  # the dashboard's own redirect
        assert r.status_code == 303 and r.headers["location"] == f"{PREFIX}/admin"
        admin = http.get(f"{PREFIX}/admin")  # with the cookie it set
        assert admin.status_code == 200 and "p-001" in admin.text
        assert "\np-001," in http.get(f"{PREFIX}/admin/export/ratings.csv").text


def test_the_app_also_answers_under_the_prefix_itself(behind_proxy):
    """A proxy that passes the path on unchanged (``proxy_pass http://upstream;``) works too."""
    proxy, upstream = behind_proxy
    token = httpx.get(f"{upstream.base}/admin/api/status", headers={"Authorization": f"Bearer {ADMIN}"}).json()
    token = token["people"][1]["link"].rsplit("/", 1)[1]
    page = httpx.get(f"{upstream.base}{PREFIX}/p/{token}")
    assert page.status_code == 200 and f'action="{PREFIX}/p/{token}/consent"' in page.text
    assert httpx.get(f"{upstream.base}{PREFIX}/static/style.css").status_code == 200
    r = httpx.post(
        f"{upstream.base}{PREFIX}/p/{token}/consent", data={"csrf": hidden(page.text, "csrf"), "agree": "yes"}
    )
    assert r.status_code == 303 and r.headers["location"] == f"{PREFIX}/p/{token}"

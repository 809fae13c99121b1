"""Shared pieces of the study tests: study files, a real server process, a scripted participant."""

from __future__ import annotations

import re
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import httpx
import yaml

EXAMPLES = Path(__file__).resolve().parents[2] / "src" / "mindgap" / "study" / "examples"
ADMIN = "admin-token-for-tests"


def study_file(tmp: Path, example: str, **changes) -> Path:
    """An example study file with some keys changed (e.g. participants, min_seconds)."""
    raw = yaml.safe_load((EXAMPLES / f"{example}.yaml").read_text())
    raw.update(changes)
    path = tmp / f"{example}.yaml"
    path.write_text(yaml.safe_dump(raw, sort_keys=False))
    return path


def driving_rollouts(path: Path, sleet: float = 1.0) -> Path:
    """A rollouts file of the driving study's testing phase: two methods' episodes (braking in lane; keeping
    the speed with grip 0.95) and a collision as the sanity episode (rated lowest)."""
    import numpy as np

    from mindgap.data.rollouts_file import rollout_record, write_rollouts
    from mindgap.envs.driving import make_world
    from mindgap.study.driving import scripted_segment

    p = make_world(sleet=sleet).params
    recs = []
    for k, (method, brake) in enumerate((("eps", True), ("sac", False))):
        seg = scripted_segment(p, 0.95, brake, 3)
        obs = np.concatenate([seg["obs"][:1], seg["next_obs"]])
        recs.append(rollout_record(f"{method}-s0-e0", method, 0, 0, obs, seg["act"], seg["mask"], 1.0 + k))
    crash = scripted_segment(p, 0.95, False, 6)
    obs = np.concatenate([crash["obs"][:1], crash["next_obs"]])
    recs.append(rollout_record("sanity", "sanity", -1, 0, obs, crash["act"], crash["mask"], sanity="lowest"))
    return write_rollouts(path, {"name": "driving", "sleet": sleet}, recs)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Server:
    """``mindgap study serve`` in a subprocess (a real uvicorn server)."""

    def __init__(
        self, config: Path, db: Path, port: int | None = None, extra: tuple[str, ...] = (), quiet: bool = True
    ):
        self.config, self.db, self.port = config, db, port or free_port()
        self.extra, self.quiet = extra, quiet
        self.proc: subprocess.Popen | None = None
        self.log = db.with_suffix(".log")

    @property
    def base(self) -> str:
        return f"http://127.0.0.1:{self.port}"

    def start(self, timeout: float = 60.0) -> Server:
        cmd = [
            sys.executable,
            "-m",
            "mindgap.cli",
            "study",
            "serve",
            "--config",
            str(self.config),
            "--db",
            str(self.db),
        ]
        cmd += ["--port", str(self.port), "--admin-token", ADMIN, *(["--quiet"] if self.quiet else []), *self.extra]
        with self.log.open("ab") as log:
            self.proc = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT)
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if self.proc.poll() is not None:
                raise RuntimeError(f"server exited with {self.proc.returncode}:\n{self.log.read_text()}")
            try:
                if httpx.get(self.base + "/healthz", timeout=1.0).status_code == 200:
                    return self
            except httpx.HTTPError:
                pass
            time.sleep(0.1)
        self.stop()
        raise RuntimeError(f"server did not come up in {timeout} s:\n{self.log.read_text()}")

    def kill(self) -> None:
        """SIGKILL: no shutdown handlers run."""
        if self.proc is not None:
            self.proc.kill()
            self.proc.wait(10)

    def stop(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(10)


def hidden(html: str, name: str) -> str:
    m = re.search(rf'name="{name}" value="([^"]*)"', html)
    if m is None:
        raise AssertionError(f"no hidden field {name!r} in page:\n{html[:2000]}")
    return m.group(1)


def form_action(html: str) -> str:
    m = re.search(r'<form method="post" action="(?:/[^/"]+)*/p/[^/"]+/(\w+)"', html)
    return m.group(1) if m else ""


class Participant:
    """A scripted participant: answers whatever page the server shows next.

    ``rate(item_id)`` gives each rating; ``acked`` collects ``{item_id: (rating, outcome)}``
    for every answer the server acknowledged (a 303 after the answer was stored);
    ``statuses`` every response's status code. With ``double_submit`` each answer form is
    sent twice at once (a double click, or a retried request, racing the first), the
    second copy from ``second`` (another connection), when given. ``prefix`` is the path the
    study is served under (``/lab`` behind a proxy).
    """

    def __init__(self, http, token: str, rate, double_submit: bool = False, second=None, prefix: str = ""):
        self.http, self.token, self.rate, self.double = http, token, rate, double_submit
        self.prefix = prefix
        self.second = second or http
        self.acked: dict[str, tuple[float, str]] = {}
        self.statuses: list[int] = []
        self.code = ""
        self.requests = 0

    def get(self) -> str:
        self.requests += 1
        r = self.http.get(f"{self.prefix}/p/{self.token}")
        self.statuses.append(r.status_code)
        assert r.status_code == 200, (r.status_code, r.text[:500])
        return r.text

    def post(self, what: str, data: dict, http=None):
        self.requests += 1
        r = (http or self.http).post(f"{self.prefix}/p/{self.token}/{what}", data=data, follow_redirects=False)
        self.statuses.append(r.status_code)
        return r

    def step(self) -> bool:
        """Answer the current page; False once the completion code is shown."""
        html = self.get()
        action = form_action(html)
        if not action:
            m = re.search(r'id="code">([0-9A-F]+)<', html)
            assert m, html[:1000]
            self.code = m.group(1)
            return False
        csrf = hidden(html, "csrf")
        if action == "consent":
            r = self.post("consent", {"csrf": csrf, "agree": "yes"})
        elif action == "instructions":
            r = self.post("instructions", {"csrf": csrf})
        elif action == "questionnaire":
            names = sorted(set(re.findall(r'type="radio" name="(\w+)" value="1"', html)))
            r = self.post("questionnaire", {"csrf": csrf, **{n: "3" for n in names}})
        else:
            item = hidden(html, "item_id")
            data = {"csrf": csrf, "item_id": item, "submission_id": hidden(html, "submission_id")}
            if 'name="rating"' in html:
                rating = self.rate(item)
                data["rating"] = str(rating)
            else:
                rating = self.rate(item)
                data["choice"] = rating
            copy: list = []
            if self.double:  # the same form sent again at once (a double click or a retried request)
                racer = threading.Thread(target=lambda: copy.append(self.post("answer", data, self.second)))
                racer.start()
            r = self.post("answer", data)
            if self.double:
                racer.join()
                r2 = copy[0]
                assert r2.status_code == 303 and r2.headers["x-answer"] in ("duplicate", "stored"), r2.text[:500]
                assert {r.headers["x-answer"], r2.headers["x-answer"]} == {"stored", "duplicate"}
            assert r.status_code == 303, (r.status_code, r.text[:500])
            assert r.headers["x-answer"] in ("stored", "duplicate", "answered"), r.headers.get("x-answer")
            self.acked[item] = (rating, r.headers["x-answer"])
        assert r.status_code == 303, (action, r.status_code, r.text[:500])
        return True

    def run(self, max_steps: int = 100) -> None:
        for _ in range(max_steps):
            if not self.step():
                return
        raise AssertionError("study did not end")

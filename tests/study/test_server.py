"""A real server process: 50 concurrent participants, a SIGKILL mid-study, the address it binds."""

import random
import threading
import time

import httpx
import pytest
from study_helpers import ADMIN, Participant, Server, study_file

from mindgap.study.store import Store

N_LOAD = 50


def _rating(seed):
    rng = random.Random(seed)
    return lambda item: 0 if item == "sanity-random" else rng.randint(1, 10)


def _check_stored_once(db, acked: dict[tuple[str, str], float]):
    """Every acknowledged answer is in the store once, with the acknowledged value; nothing else is."""
    store = Store(db)
    by_token = {p["id"]: p["token"] for p in store.participants()}
    rows = store.conn().execute("SELECT participant_id, item_id, value FROM answers").fetchall()
    keys = [(by_token[r[0]], r[1]) for r in rows]
    assert len(keys) == len(set(keys))  # one row per participant and item
    stored = {(by_token[r[0]], r[1]): r[2] for r in rows}
    missing = [k for k in acked if k not in stored]
    assert not missing, f"acknowledged but not stored: {missing[:5]}"
    assert all(stored[k] == v for k, v in acked.items())
    return stored


def test_fifty_participants_at_once_every_answer_stored_once(tmp_path):
    config = study_file(tmp_path, "coffee-rating", participants=N_LOAD, min_seconds=0)
    server = Server(config, tmp_path / "load.sqlite").start()
    try:
        tokens = [p["token"] for p in Store(server.db).participants()]
        people, errors = [], []

        def one(i, token):
            try:
                with httpx.Client(base_url=server.base, timeout=30.0) as http:
                    p = Participant(http, token, _rating(i), double_submit=i % 5 == 0)  # every fifth double-clicks
                    people.append(p)
                    p.run()
            except Exception as e:  # noqa: BLE001 - reported below with the participant
                errors.append((i, repr(e)))

        threads = [threading.Thread(target=one, args=(i, t)) for i, t in enumerate(tokens)]
        start = time.perf_counter()
        for t in threads:
            t.start()
        for t in threads:
            t.join(timeout=120)
        wall = time.perf_counter() - start
        assert not any(t.is_alive() for t in threads), "participants still running after 120 s"
        assert not errors, errors[:3]
        acked = {(p.token, item): float(v) for p in people for item, (v, _) in p.acked.items()}
        assert len(acked) == N_LOAD * 9 and all(p.code for p in people)
        stored = _check_stored_once(server.db, acked)
        assert len(stored) == N_LOAD * 9
        requests = sum(p.requests for p in people)
        status = httpx.get(server.base + "/admin/api/status", headers={"Authorization": f"Bearer {ADMIN}"}).json()
        assert status["n_done"] == N_LOAD and status["n_answers"] == N_LOAD * 9
        print(
            f"\nload: {N_LOAD} participants, {len(acked)} answers, {requests} requests in {wall:.1f} s "
            f"({len(acked) / wall:.0f} answers/s, {requests / wall:.0f} requests/s)"
        )
        assert wall < 120
    finally:
        server.stop()


def test_a_killed_server_loses_no_acknowledged_answer_and_participants_continue(tmp_path):
    config = study_file(tmp_path, "coffee-rating", participants=8, min_seconds=0)
    server = Server(config, tmp_path / "crash.sqlite").start()
    tokens = [p["token"] for p in Store(server.db).participants()]
    people = [Participant(httpx.Client(base_url=server.base, timeout=5.0), t, _rating(i)) for i, t in enumerate(tokens)]
    stop = threading.Event()

    def answer_until_the_crash(p):
        try:
            while not stop.is_set() and p.step():
                pass
        except (httpx.HTTPError, AssertionError):
            pass  # the server died under this participant

    threads = [threading.Thread(target=answer_until_the_crash, args=(p,)) for p in people]
    try:
        for t in threads:
            t.start()
        deadline = time.monotonic() + 30
        while sum(len(p.acked) for p in people) < 20 and time.monotonic() < deadline:
            time.sleep(0.02)
        server.kill()  # SIGKILL while requests are in flight
        stop.set()
        for t in threads:
            t.join(timeout=30)
        before = {(p.token, item): float(v) for p in people for item, (v, _) in p.acked.items()}
        assert 20 <= len(before) < len(people) * 9, len(before)
        server.start()  # same store, same port
        _check_stored_once(server.db, before)
        for p in people:  # everyone continues where they stopped and finishes
            p.run()
            assert p.code
        after = {(p.token, item): float(v) for p in people for item, (v, _) in p.acked.items()}
        stored = _check_stored_once(server.db, after)
        assert len(stored) == len(people) * 9
        print(f"\ncrash: {len(before)} answers acknowledged before SIGKILL, all found after restart; all finished")
    finally:
        stop.set()
        server.stop()
        for p in people:
            p.http.close()


def test_the_server_listens_on_localhost_only(tmp_path):
    server = Server(study_file(tmp_path, "coffee-rating", participants=1), tmp_path / "bind.sqlite").start()
    try:
        listening = _listening_addresses(server.port)
        assert listening == {"127.0.0.1"}, listening
    finally:
        server.stop()


def _listening_addresses(port: int) -> set[str]:
    """Local addresses of sockets in LISTEN state on ``port`` (Linux /proc/net/tcp{,6})."""
    found = set()
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        try:
            lines = open(table).read().splitlines()[1:]
        except OSError:
            pytest.skip("no /proc/net/tcp on this system")
        for line in lines:
            local, state = line.split()[1], line.split()[3]
            addr, p = local.split(":")
            if state == "0A" and int(p, 16) == port:
                if len(addr) == 8:
                    found.add(".".join(str(int(addr[i : i + 2], 16)) for i in (6, 4, 2, 0)))
                else:
                    found.add(addr)
    return found

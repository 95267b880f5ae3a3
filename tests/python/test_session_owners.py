"""Sessions among several clients (issue 23, items 4 and 6): a session belongs
to the client that created it (its bearer token, or its address without
tokens), every other client gets the 404 of a missing session; one client
holds at most --max-sessions-per-client sessions, and when the store is full
the client holding the most gives way: a client creating sessions as fast as
it can never evicts another's; the logs show a session's tag, never its id.
No timing is asserted: the churner makes a bounded number of sessions, and
whatever the schedule, no solver step may be refused."""
import hashlib
import http.client
import json
import re
import threading

import pytest
import requests

from conftest import start_daemon

SCENE = json.dumps({"version": 1, "options": {"penalty": 10.0},
                    "bodies": [{"id": "a", "nodes": [[0, 0], [1, 0], [1, 1], [0, 1]]},
                               {"id": "b", "nodes": [[0.9, 0.1], [2, 0.1], [2, 0.9], [0.9, 0.9]]}]}).encode()
JSON = {"Content-Type": "application/json"}


class Client:
    """One client of the daemon: a keep-alive connection from a source address
    (127.0.0.0/8 reaches the daemon from any of its addresses), with a token or
    none. request() -> (status, headers, body)."""

    def __init__(self, d, source="127.0.0.1", token=None):
        self.d, self.source, self.token = d, source, token
        self.conn = None

    def request(self, method, path, body=None, headers=None):
        h = dict(headers or {})
        if self.token:
            h["Authorization"] = f"Bearer {self.token}"
        for attempt in range(2):
            if self.conn is None:
                self.conn = http.client.HTTPConnection("127.0.0.1", self.d.port, timeout=60,
                                                       source_address=(self.source, 0))
            try:
                self.conn.request(method, path, body=body, headers=h)
                r = self.conn.getresponse()
                data = r.read()
                if r.getheader("Connection", "").lower() == "close":
                    self.close()
                return r.status, {k.lower(): v for k, v in r.getheaders()}, data
            except (ConnectionError, http.client.HTTPException):
                self.close()  # a keep-alive connection the daemon closed: once more on a new one
                if attempt:
                    raise
        raise AssertionError("unreachable")

    def create(self):
        status, headers, body = self.request("POST", "/v1/scenes", SCENE, JSON)
        return status, (json.loads(body)["id"] if status == 201 else body)

    def step(self, sid):
        return self.request("POST", f"/v1/scenes/{sid}/contact")[0]

    def close(self):
        if self.conn is not None:
            self.conn.close()
            self.conn = None


def health(d, token=None):
    h = {"Authorization": f"Bearer {token}"} if token else {}
    return requests.get(d.url("/v1/health"), headers=h, timeout=10).json()["sessions"]


def one_session_bytes(paths, tmp_path):
    probe = start_daemon(paths.bin / "ntscontactd", tmp_path / "probe.log")
    try:
        c = Client(probe)
        status, sid = c.create()
        assert status == 201 and c.step(sid) == 200
        c.close()
        return health(probe)["memory_bytes"]
    finally:
        assert probe.stop() == 0


def clients_of(d, how, tokens):
    """Four solvers and a churner: by token (all from 127.0.0.1), or by address."""
    if how == "tokens":
        return [Client(d, token=t) for t in tokens[:4]], Client(d, token=tokens[4])
    return [Client(d, source=f"127.0.0.{2 + i}") for i in range(4)], Client(d, source="127.0.0.9")


# ------------------------------------------------------------ item 4: quotas

CHURNED = 300  # sessions the churner asks for: bounded by count, not by time


@pytest.mark.parametrize("pressure", ["quota", "count", "memory"])
@pytest.mark.parametrize("how", ["tokens", "addresses"])
def test_a_churning_client_never_evicts_the_solvers(paths, tmp_path, how, pressure):
    """4 solver sessions stepping in a loop while another client creates
    sessions as fast as it can: no solver step is ever refused (0
    re-creations), and the churner only ever evicted its own sessions. What
    binds: the churner's quota (--max-sessions-per-client 2 of 8), the
    store's count (--max-sessions 6, no quota below it: the churner fills the
    2 free places, then must give its own), or its memory (room for 8 stepped
    sessions; idle ones give back their buffers first, then are evicted)."""
    tokens = [f"client-token-{i}" for i in range(5)]
    (tmp_path / "tokens").write_text("\n".join(tokens) + "\n")
    flags = ["--threads", "2"]
    if how == "tokens":
        flags += ["--token-file", str(tmp_path / "tokens")]
    if pressure == "quota":
        flags += ["--max-sessions", "8", "--max-sessions-per-client", "2"]
    elif pressure == "count":
        flags += ["--max-sessions", "6", "--max-sessions-per-client", "6"]
    else:
        # Room for 8 sessions as a step leaves them; the count and the quota (a
        # quarter of 4000) never bind.
        flags += ["--session-memory", str(8 * one_session_bytes(paths, tmp_path) + 4096), "--max-sessions", "4000"]
    d = start_daemon(paths.bin / "ntscontactd", tmp_path / "d.log", *flags)
    try:
        solvers, churner = clients_of(d, how, tokens)
        ids = []
        for c in solvers:
            status, sid = c.create()
            assert status == 201, sid
            ids.append(sid)
        done = threading.Event()
        churned = {"created": 0, "other": []}

        def churn():
            try:
                for _ in range(CHURNED):
                    status, body = churner.create()
                    if status == 201:
                        churned["created"] += 1
                    else:
                        churned["other"].append((status, body[:200]))
            finally:
                done.set()

        t = threading.Thread(target=churn)
        t.start()
        statuses, rounds = {}, 0
        while not done.is_set() or rounds < 5:
            for c, sid in zip(solvers, ids):
                s = c.step(sid)
                statuses[s] = statuses.get(s, 0) + 1
            rounds += 1
        t.join()
        assert statuses == {200: 4 * rounds}, statuses  # never a 404: no re-creation
        # The churner's own sessions always made room: it was never refused.
        assert churned == {"created": CHURNED, "other": []}, churned
        for c, sid in zip(solvers, ids):
            status, _, body = c.request("GET", f"/v1/scenes/{sid}")
            assert status == 200 and json.loads(body)["steps"] == rounds
        h = health(d, tokens[0] if how == "tokens" else None)
        print(f"{how}, {pressure}: {rounds} rounds of 4 steps, churner {churned}, sessions {h}")
        # Every eviction was of the churner's own sessions, and it kept at most
        # what the binding limit leaves it.
        assert h["evicted"] == h["evicted_own"] and h["refused"] == 0, h
        kept = {"quota": 2, "count": 2}.get(pressure)
        if kept is not None:
            assert h["held"] == 4 + kept and h["evicted_own"] == CHURNED - kept, h
        else:
            assert h["evicted_own"] > 0 and h["memory_bytes"] <= h["memory_max"], h
        assert h["created"] == 4 + CHURNED and h["clients"] == 5, h
        for c in solvers + [churner]:
            c.close()
    finally:
        assert d.stop() == 0, d.log()[-2000:]


def test_a_client_at_its_quota_evicts_its_own_oldest(paths, tmp_path):
    d = start_daemon(paths.bin / "ntscontactd", tmp_path / "d.log", "--max-sessions", "8",
                     "--max-sessions-per-client", "2")
    try:
        me, other = Client(d, source="127.0.0.2"), Client(d, source="127.0.0.3")
        status, theirs = other.create()
        assert status == 201
        mine = []
        for _ in range(3):
            status, sid = me.create()
            assert status == 201
            mine.append(sid)
        assert me.step(mine[0]) == 404  # its own oldest made room for its third
        assert me.step(mine[1]) == 200 and me.step(mine[2]) == 200
        assert other.step(theirs) == 200
        h = health(d)
        assert h["held"] == 3 and h["evicted"] == 1 and h["evicted_own"] == 1 and h["clients"] == 2
        assert h["max_per_client"] == 2
        me.close()
        other.close()
    finally:
        assert d.stop() == 0


@pytest.mark.parametrize("read", ["surface", "metadata", "step"])
def test_reading_a_session_leaves_its_place_among_the_least_recently_used(paths, tmp_path, read):
    """A client at its quota of 2 reads its older session (its surface, its
    metadata: not a use; a step: a use), then creates a third: the older is
    evicted unless the read was a step, which makes the newer the least
    recently used."""
    d = start_daemon(paths.bin / "ntscontactd", tmp_path / "d.log", "--max-sessions", "8",
                     "--max-sessions-per-client", "2")
    try:
        me = Client(d)
        older, newer = (me.create()[1] for _ in range(2))
        if read == "step":
            assert me.step(older) == 200
        else:
            status, _, _ = me.request("GET", f"/v1/scenes/{older}" + ("/surface" if read == "surface" else ""))
            assert status == 200
        status, third = me.create()
        assert status == 201
        gone, kept = (newer, older) if read == "step" else (older, newer)
        assert me.step(gone) == 404 and me.step(kept) == 200 and me.step(third) == 200
        assert health(d)["evicted_own"] == 1
        me.close()
    finally:
        assert d.stop() == 0


@pytest.mark.parametrize("max_sessions,quota", [("2", 2), ("8", 4), ("64", 16), ("1000", 250)])
def test_the_default_quota_is_a_quarter_of_the_store_at_least_4(paths, tmp_path, max_sessions, quota):
    d = start_daemon(paths.bin / "ntscontactd", tmp_path / "d.log", "--max-sessions", max_sessions)
    try:
        assert health(d)["max_per_client"] == quota
    finally:
        assert d.stop() == 0


def test_a_full_store_takes_from_the_client_holding_the_most(paths, tmp_path):
    """--max-sessions 4, each client may hold 4: the store is full with a
    client's 3 and another's 1; a third client's session takes one of the 3,
    never the lone one, though that one is the least recently used."""
    d = start_daemon(paths.bin / "ntscontactd", tmp_path / "d.log", "--max-sessions", "4",
                     "--max-sessions-per-client", "4")
    try:
        lone, big, new = Client(d, source="127.0.0.2"), Client(d, source="127.0.0.3"), Client(d, source="127.0.0.4")
        status, oldest = lone.create()
        assert status == 201
        many = [big.create()[1] for _ in range(3)]
        status, sid = new.create()
        assert status == 201
        assert lone.step(oldest) == 200
        assert [big.step(x) for x in many] == [404, 200, 200]  # the big client's least recently used
        assert new.step(sid) == 200
        h = health(d)
        assert h["evicted"] == 1 and h["evicted_own"] == 0
        for c in (lone, big, new):
            c.close()
    finally:
        assert d.stop() == 0


def test_a_full_store_of_equals_takes_the_least_recently_used_then_the_newcomers_own(paths, tmp_path):
    """--max-sessions 4, four clients holding one each: a fifth client's
    session takes the least recently used of them (all hold as much); its
    next one takes its own first, never a second from the others."""
    d = start_daemon(paths.bin / "ntscontactd", tmp_path / "d.log", "--max-sessions", "4",
                     "--max-sessions-per-client", "4")
    try:
        holders = [Client(d, source=f"127.0.0.{2 + i}") for i in range(4)]
        ids = [c.create()[1] for c in holders]
        for k in (2, 0, 3, 1):  # the third is now the least recently used, not the first created
            assert holders[k].step(ids[k]) == 200
        new = Client(d, source="127.0.0.9")
        status, first = new.create()
        assert status == 201
        assert [c.step(sid) for c, sid in zip(holders, ids)] == [200, 200, 404, 200]
        status, second = new.create()
        assert status == 201
        assert new.step(first) == 404 and new.step(second) == 200
        assert [holders[k].step(ids[k]) for k in (0, 1, 3)] == [200, 200, 200]
        h = health(d)
        assert h["evicted"] == 2 and h["evicted_own"] == 1 and h["held"] == 4, h
        for c in holders + [new]:
            c.close()
    finally:
        assert d.stop() == 0


# ------------------------------------------------------------ item 6: ownership

def test_a_session_belongs_to_its_token(paths, tmp_path):
    (tmp_path / "tokens").write_text("owner-token\nother-token\n")
    d = start_daemon(paths.bin / "ntscontactd", tmp_path / "d.log", "--token-file", str(tmp_path / "tokens"))
    try:
        owner, other = Client(d, token="owner-token"), Client(d, token="other-token")
        status, sid = owner.create()
        assert status == 201
        missing = other.request("GET", "/v1/scenes/" + "A" * 43)
        for method, path in (("GET", f"/v1/scenes/{sid}"), ("POST", f"/v1/scenes/{sid}/contact"),
                             ("GET", f"/v1/scenes/{sid}/surface"), ("DELETE", f"/v1/scenes/{sid}"),
                             ("HEAD", f"/v1/scenes/{sid}")):
            status, _, body = other.request(method, path)
            assert status == 404, (method, status, body)
            if method != "HEAD":  # the same answer as for an id that does not exist
                assert body == missing[2] and json.loads(body)["error"]["code"] == "unknown_scene"
        # Nothing happened to it.
        assert owner.step(sid) == 200
        status, _, body = owner.request("GET", f"/v1/scenes/{sid}")
        assert status == 200 and json.loads(body)["steps"] == 1
        assert owner.request("DELETE", f"/v1/scenes/{sid}")[0] == 204
        owner.close()
        other.close()
    finally:
        assert d.stop() == 0


def test_without_tokens_a_session_belongs_to_its_address(paths, tmp_path):
    d = start_daemon(paths.bin / "ntscontactd", tmp_path / "d.log")
    try:
        owner, other = Client(d, source="127.0.0.2"), Client(d, source="127.0.0.3")
        status, sid = owner.create()
        assert status == 201
        assert other.step(sid) == 404
        assert other.request("DELETE", f"/v1/scenes/{sid}")[0] == 404
        assert owner.step(sid) == 200
        owner.close()
        other.close()
    finally:
        assert d.stop() == 0


def test_behind_a_trusted_proxy_a_session_belongs_to_the_forwarded_address(paths, tmp_path):
    """The proxy's own address is not who the client is: two addresses it
    forwards are two owners."""
    d = start_daemon(paths.bin / "ntscontactd", tmp_path / "d.log", "--trusted-proxy", "127.0.0.1")
    try:
        proxy = Client(d)
        one, two = {"X-Forwarded-For": "192.0.2.1"}, {"X-Forwarded-For": "198.51.100.7, 192.0.2.2"}
        status, _, body = proxy.request("POST", "/v1/scenes", SCENE, {**JSON, **one})
        assert status == 201
        sid = json.loads(body)["id"]
        assert proxy.request("POST", f"/v1/scenes/{sid}/contact", headers=two)[0] == 404
        assert proxy.request("GET", f"/v1/scenes/{sid}", headers=two)[0] == 404
        assert proxy.request("POST", f"/v1/scenes/{sid}/contact", headers=one)[0] == 200
        # The client's word before the proxy's last address is not who it is.
        assert proxy.request("GET", f"/v1/scenes/{sid}", headers={"X-Forwarded-For": "192.0.2.2, 192.0.2.1"})[0] == 200
        proxy.close()
    finally:
        assert d.stop() == 0


# ------------------------------------------------------------ item 6: logs

def tag(sid):
    """What the logs show for a session id: docs/operations.md, "Logs"."""
    return "~" + hashlib.sha256(sid.encode()).hexdigest()[:8]


@pytest.mark.parametrize("fmt", ["text", "json"])
def test_logs_show_a_tag_never_the_id(paths, tmp_path, fmt):
    log = tmp_path / "daemon.log"
    d = start_daemon(paths.bin / "ntscontactd", tmp_path / "stderr.log", "--log-file", str(log),
                     "--log-format", fmt)
    try:
        c = Client(d)
        ids = []
        for _ in range(2):
            status, sid = c.create()
            assert status == 201
            ids.append(sid)
            assert c.step(sid) == 200
            assert c.request("GET", f"/v1/scenes/{sid}")[0] == 200
            assert c.request("POST", f"/v1/scenes/{sid}/contact", b"{", JSON)[0] == 400
            assert c.request("DELETE", f"/v1/scenes/{sid}")[0] == 204
            assert c.step(sid) == 404
        # Mistyped paths with an id in them: no id either.
        assert c.request("GET", f"/v1/scenes//{ids[0]}")[0] == 404
        assert c.request("POST", f"/v1/scenes/{ids[0]}/contacts")[0] == 404
        c.close()
    finally:
        assert d.stop() == 0
    text = log.read_text() + d.log()
    for sid in ids:
        assert sid not in text
        for k in range(0, 43 - 12, 6):  # nor any dozen of its characters
            assert sid[k:k + 12] not in text
    if fmt == "json":
        paths_logged = [x["path"] for x in map(json.loads, log.read_text().splitlines()) if x["event"] == "request"]
    else:
        paths_logged = [line.split()[3] for line in text.splitlines() if " /v1/" in line]
    tags = [p for p in paths_logged if p.startswith("/v1/scenes/")]
    first, second = tag(ids[0]), tag(ids[1])
    assert first != second
    assert tags == [f"/v1/scenes/{first}/contact", f"/v1/scenes/{first}", f"/v1/scenes/{first}/contact",
                    f"/v1/scenes/{first}", f"/v1/scenes/{first}/contact"] + \
                   [f"/v1/scenes/{second}/contact", f"/v1/scenes/{second}", f"/v1/scenes/{second}/contact",
                    f"/v1/scenes/{second}", f"/v1/scenes/{second}/contact"] + \
                   [f"/v1/scenes//{first}", f"/v1/scenes/{first}/{tag('contacts')}"], tags  # every segment but "contact"


def test_the_tag_is_the_sha256_of_any_id_length(paths, tmp_path):
    """A proxy's ids (--session-id-header) are 32 to 64 characters: the tag
    is SHA-256's across its padding boundaries (55/56 bytes: one block or
    two; 64: two), as `sha256sum` gives it."""
    log = tmp_path / "daemon.log"
    d = start_daemon(paths.bin / "ntscontactd", tmp_path / "stderr.log", "--log-file", str(log),
                     "--session-id-header", "X-Request-Id")
    ids = ["a" * 32, "b" * 43, "c" * 55, "d" * 56, "e" * 63, "f" * 64]
    try:
        c = Client(d)
        for sid in ids:
            status, _, body = c.request("POST", "/v1/scenes", SCENE, {**JSON, "X-Request-Id": sid})
            assert status == 201 and json.loads(body)["id"] == sid
            assert c.step(sid) == 200
        c.close()
    finally:
        assert d.stop() == 0
    text = log.read_text()
    for sid in ids:
        assert sid not in text
        assert f"POST /v1/scenes/{tag(sid)}/contact 200" in text, (sid, tag(sid))

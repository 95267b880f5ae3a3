"""The client's own kept connection (ntscontact._wire): what it must do as
urllib3 did, against a scripted server (answers chunked, close-delimited,
compressed, after an interim 100, a connection closed while idle, an answer
never sent or cut) and against the daemon (the same answers as urllib3's
path, bit for bit, from several threads at once)."""
import gzip
import json
import select
import socket
import threading
import time

import numpy as np
import pytest

from conftest import positions_of
from ntscontact import Client, NtsError, ServiceUnavailable, Timeout  # noqa: E402
from ntscontact._wire import Wire, WireHeaders


class Scripted:
    """A server on 127.0.0.1: each request read whole (head and
    Content-Length body) is given to ``answer(k, head, body)`` (k counts the
    requests), which returns the bytes to send back, and "close" to close the
    connection after them, or None to close without answering; bytes in a
    list are sent apart, a moment between them (an answer in pieces)."""

    def __init__(self, answer):
        self.answer = answer
        self.requests = []
        self.connections = 0
        self.lsock = socket.socket()
        self.lsock.bind(("127.0.0.1", 0))
        self.lsock.listen(8)
        self.port = self.lsock.getsockname()[1]
        self.conns = []
        threading.Thread(target=self._serve, daemon=True).start()

    def _serve(self):
        while True:
            try:
                c, _ = self.lsock.accept()
            except OSError:
                return
            self.connections += 1
            self.conns.append(c)
            threading.Thread(target=self._conn, args=(c,), daemon=True).start()

    def _conn(self, c):
        buf = b""
        try:
            while True:
                while b"\r\n\r\n" not in buf:
                    piece = c.recv(65536)
                    if not piece:
                        return
                    buf += piece
                head, _, buf = buf.partition(b"\r\n\r\n")
                n = 0
                for line in head.split(b"\r\n")[1:]:
                    k, _, v = line.partition(b":")
                    if k.strip().lower() == b"content-length":
                        n = int(v)
                while len(buf) < n:
                    buf += c.recv(65536)
                body, buf = buf[:n], buf[n:]
                self.requests.append((head.decode("latin-1"), body))
                out = self.answer(len(self.requests) - 1, head.decode("latin-1"), body)
                if out is None:
                    c.close()
                    return
                data, close = out if isinstance(out, tuple) else (out, False)
                for k, piece in enumerate(data if isinstance(data, list) else [data]):
                    if k:
                        time.sleep(0.05)
                    c.sendall(piece)
                if close:
                    c.close()
                    return
        except OSError:
            return

    def close(self):
        self.lsock.close()
        for c in self.conns:
            try:
                c.close()
            except OSError:
                pass

    @property
    def url(self):
        return f"http://127.0.0.1:{self.port}"


def ok(body=b'{"status": "ok"}', extra=""):
    return (f"HTTP/1.1 200 OK\r\nContent-Type: application/json\r\nContent-Length: {len(body)}\r\n{extra}\r\n"
            ).encode() + body


@pytest.fixture
def scripted():
    made = []

    def make(answer):
        made.append(Scripted(answer))
        return made[-1]
    yield make
    for s in made:
        s.close()


def test_one_connection_and_the_head_sent(scripted):
    """Many calls on one connection; the head carries the client's headers,
    the path prefix, the query and the body's length; the answer's headers
    are read case-insensitively."""
    srv = scripted(lambda k, head, body: ok(extra="NTS-Elapsed-Ms: 1.5\r\n"))
    with Client(srv.url + "/api", timeout=10, token="t0k") as c:
        for _ in range(5):
            assert c.health()["status"] == "ok"
        answer = c._send("POST", "/v1/x", body=b"abc", params={"a": "1"},
                         headers={"Content-Type": "text/plain", "accept": "x/y"})
        assert answer.headers["nts-elapsed-ms"] == "1.5" and answer.headers.get("NTS-ELAPSED-MS") == "1.5"
    assert srv.connections == 1 and len(srv.requests) == 6
    head, body = srv.requests[-1]
    lines = head.split("\r\n")
    assert lines[0] == "POST /api/v1/x?a=1 HTTP/1.1" and body == b"abc"
    fields = {k.lower(): v.strip() for k, _, v in (ln.partition(":") for ln in lines[1:])}
    assert fields["content-length"] == "3" and fields["authorization"] == "Bearer t0k"
    assert fields["user-agent"].startswith("ntscontact-python/") and fields["content-type"] == "text/plain"
    # the call's Accept replaces the client's (names in any case), never both
    assert head.lower().count("\r\naccept:") == 1 and fields["accept"] == "x/y"


def test_answers_chunked_close_delimited_compressed_and_after_100(scripted):
    doc = json.dumps({"status": "ok", "pad": "x" * 5000}).encode()
    z = gzip.compress(doc)
    chunked = b"".join(b"%x;ext=1\r\n%s\r\n" % (len(doc[i:i + 999]), doc[i:i + 999]) for i in range(0, len(doc), 999))
    answers = [
        [b"HTTP/1.1 200 OK\r\nTransfer-Encoding: chunked\r\n\r\n" + chunked[:1500], chunked[1500:] + b"0\r\n",
         b"X-Trailer: 1\r\n\r\n"],
        b"HTTP/1.1 100 Continue\r\n\r\n" + ok(doc),
        ok(z, extra="Content-Encoding: gzip\r\n"),
        (b"HTTP/1.0 200 OK\r\nContent-Type: application/json\r\n\r\n" + doc, "close"),
        ok(doc),
    ]
    srv = scripted(lambda k, head, body: answers[k])
    with Client(srv.url, timeout=10) as c:
        for _ in answers:
            got = c.health()
            assert got["status"] == "ok" and len(got["pad"]) == 5000
        assert c._wire.exchanges == len(answers)
    assert srv.connections == 2  # the close-delimited answer ended its connection


def test_connection_close_and_an_idle_connection_closed_by_the_peer(scripted):
    """An answer saying Connection: close ends the connection; one the peer
    closed while idle is replaced before it is used: every request sent
    once, every answer read."""
    def answer(k, head, body):
        if k == 0:
            return ok(extra="Connection: close\r\n"), "close"
        if k == 2:  # answered, then the server closes while the client is idle
            return ok(), "close"
        return ok()
    srv = scripted(answer)
    with Client(srv.url, timeout=10) as c:
        assert c.health()["status"] == "ok"  # 0: closed after it
        assert c.health()["status"] == "ok"  # 1: a new connection
        assert c.health()["status"] == "ok"  # 2
        ready = select.poll()  # the server's close has reached the client (no sleep: a busy machine is slow)
        ready.register(c._wire.sock, select.POLLIN)
        assert ready.poll(60000)
        assert c.health()["status"] == "ok"  # 3: a new connection, the request sent once
        assert c._wire.connections == 3
    assert len(srv.requests) == 4 and srv.connections == 3


def test_an_answer_cut_or_never_sent(scripted):
    """A request sent whole is never sent again: the connection closed with
    no answer is ServiceUnavailable, a truncated body too; no answer within
    the read timeout is Timeout."""
    srv = scripted(lambda k, head, body: None)
    with Client(srv.url, timeout=10) as c:
        with pytest.raises(ServiceUnavailable) as e:
            c.health()
        assert e.value.code == "unreachable" and e.value.status is None
    assert len(srv.requests) == 1

    srv = scripted(lambda k, head, body: (b"HTTP/1.1 200 OK\r\nContent-Length: 100\r\n\r\n{\"a\":", "close"))
    with Client(srv.url, timeout=10) as c:
        with pytest.raises(ServiceUnavailable):
            c.health()
    assert len(srv.requests) == 1

    gate = threading.Event()
    srv = scripted(lambda k, head, body: (gate.wait(30), ok())[1])
    with Client(srv.url, timeout=0.5) as c:
        with pytest.raises(Timeout) as e:  # (the answer comes only once the gate opens, after this)
            c.health()
        assert e.value.code == "timeout"
        gate.set()
    assert len(srv.requests) == 1

    srv = scripted(lambda k, head, body: b"SMTP ready\r\n\r\n")
    with Client(srv.url, timeout=10) as c:
        with pytest.raises(ServiceUnavailable):
            c.health()


def test_a_refused_connection_is_retried_then_unreachable():
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()  # nothing listens there
    with Client(f"http://127.0.0.1:{port}", timeout=5, retries=2, backoff=0.0) as c:
        with pytest.raises(ServiceUnavailable) as e:
            c.health()
        assert e.value.code == "unreachable" and "cannot connect" in str(e.value)


def test_wire_headers_and_a_head_too_long(scripted):
    h = WireHeaders({"content-length": "3"})
    assert h["Content-Length"] == "3" and "CONTENT-LENGTH" in h and h.get("x") is None and 3 not in h
    srv = scripted(lambda k, head, body: b"HTTP/1.1 200 OK\r\n" + b"X: " + b"y" * 70000 + b"\r\n\r\n")
    w = Wire("127.0.0.1", srv.port, retries=0)
    with pytest.raises(OSError):
        w.exchange("GET", "/", {}, None, 5, 5)
    w.close()


def test_steps_from_threads_and_both_paths_bitwise(daemon, paths):
    """Four threads stepping their sessions on one client (the kept
    connection serves one call at a time; the others take urllib3's pool):
    every answer is what urllib3's path alone gives, bit for bit."""
    scene = json.loads((paths.examples / "jittered_packing.json").read_text())
    x0 = positions_of(scene)
    rng = np.random.default_rng(3)
    frames = [x0 + rng.normal(scale=1e-3, size=x0.shape) for _ in range(12)]
    with Client(daemon.base, timeout=60, wire=False) as ref:
        with ref.session(scene) as s:
            want = [s.contact(f).force_array().copy() for f in frames]
    got = {}
    errors = []
    with Client(daemon.base, timeout=60) as c:
        def run(t):
            try:
                with c.session(scene) as s:
                    got[t] = [s.contact(f).force_array() for f in frames]
            except Exception as exc:  # (reported below)
                errors.append(exc)
        threads = [threading.Thread(target=run, args=(t,)) for t in range(4)]
        for t in threads:
            t.start()
        for t in threads:
            t.join(120)
        assert c._wire is not None and c._wire.exchanges > 0
    assert not errors and len(got) == 4
    for t in got:
        for a, b in zip(got[t], want):
            assert np.array_equal(a, b)


def test_a_step_error_through_the_wire(daemon, paths):
    """The service's refusals come back typed with their pointer, as on
    urllib3's path: non-finite positions (the client leaves them to the
    service), a wrong count."""
    scene = json.loads((paths.examples / "two_disks.json").read_text())
    pos = positions_of(scene)
    for wire in (True, False):
        with Client(daemon.base, timeout=60, wire=wire) as c, c.session(scene) as s:
            bad = pos.copy()
            bad[3, 1] = np.nan
            with pytest.raises(NtsError) as e:
                s.contact(bad)
            assert e.value.status == 400 and e.value.code == "non_finite" and e.value.pointer == "/positions/3"
            assert np.array_equal(s.positions(), pos)  # the stored positions are not the refused ones
            assert s.contact(pos).force_array().shape == pos.shape


def test_a_call_abandoned_after_sending_leaves_no_answer_behind(scripted):
    """The caller's work between sending and reading fails (or an interrupt):
    the connection is dropped with the answer unread, and the next call
    reads its own answer, not that one."""
    srv = scripted(lambda k, head, body: ok(json.dumps({"path": head.split(" ")[1]}).encode()))
    w = Wire("127.0.0.1", srv.port, retries=0)

    def fail():
        raise RuntimeError("the caller's work failed")
    with pytest.raises(RuntimeError):
        w.exchange("GET", "/a", {}, None, 5, 5, while_waiting=fail)
    status, _, content, _ = w.exchange("GET", "/b", {}, None, 5, 5)
    assert status == 200 and json.loads(content) == {"path": "/b"} and w.connections == 2
    w.close()


@pytest.mark.parametrize("reused", [False, True])
def test_an_answer_before_the_body_is_read(daemon_factory, reused):
    """The daemon answers a body over --max-bytes before reading it (413)
    and closes: the client reads that answer (PayloadTooLarge), on a new
    connection or a kept one, and sends the request once."""
    from ntscontact import PayloadTooLarge
    d = daemon_factory("--max-bytes", "1k")
    with Client(d.base, timeout=30) as c:
        if reused:
            assert c.health()["status"] == "ok"
        before = c._wire.exchanges if c._wire else 0
        with pytest.raises(PayloadTooLarge) as e:
            c._call("POST", "/v1/contact", body=b" " * (16 << 20), headers={"Content-Type": "application/json"})
        assert e.value.status == 413 and e.value.code == "payload_too_large"
        assert c._wire.exchanges == before + 1 and c._wire.connections == 1
        assert c.health()["status"] == "ok"  # and on: a new connection
        assert c._wire.connections == 2


def test_a_header_with_a_newline_is_refused_before_sending(scripted):
    """A token read with its newline: refused as http.client refuses it, not
    sent as a head that ends early."""
    srv = scripted(lambda k, head, body: ok())
    with Client(srv.url, timeout=10, token="t0k\n") as c:
        with pytest.raises(ValueError):
            c.health()
    w = Wire("127.0.0.1", srv.port, retries=0)
    for target in ("/a b", "/a\r\nX: 1"):
        with pytest.raises(ValueError):
            w.exchange("GET", target, {}, None, 5, 5)
    with pytest.raises(ValueError):
        w.exchange("GET", "/", {"X-A": "1\r\nX-B: 2"}, None, 5, 5)
    assert srv.requests == []
    # a Host or Content-Length of the caller's is not sent twice
    w.exchange("POST", "/", {"Host": "elsewhere", "content-length": "99"}, b"ab", 5, 5)
    head = srv.requests[0][0].lower()
    assert head.count("host:") == 1 and head.count("content-length:") == 1 and "content-length: 2" in head
    w.close()


def test_descriptors_above_1024_keep_the_connection(scripted):
    """select() refuses descriptors from 1024 on; a solver holding many
    files must not open a connection a call."""
    import resource
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    if hard != resource.RLIM_INFINITY and hard < 1200:
        pytest.skip(f"the hard limit of descriptors is {hard}")
    resource.setrlimit(resource.RLIMIT_NOFILE, (max(soft, 1200) if soft != resource.RLIM_INFINITY else soft, hard))
    import os
    held = []
    try:
        while len(held) < 1100:
            held.append(os.open("/dev/null", os.O_RDONLY))
        srv = scripted(lambda k, head, body: ok())
        with Client(srv.url, timeout=10) as c:
            for _ in range(5):
                assert c.health()["status"] == "ok"
            assert c._wire.sock.fileno() >= 1024 and c._wire.connections == 1
        assert srv.connections == 1
    finally:
        for fd in held:
            os.close(fd)
        resource.setrlimit(resource.RLIMIT_NOFILE, (soft, hard))


def test_connect_attempts_are_the_retries(monkeypatch):
    """A refused connection: 1 + retries attempts, then unreachable."""
    import ntscontact._wire as wire_mod
    calls = []

    def refuse(addr, timeout=None):
        calls.append(addr)
        raise ConnectionRefusedError("refused")
    monkeypatch.setattr(wire_mod.socket, "create_connection", refuse)
    with Client("http://127.0.0.1:9", timeout=5, retries=2, backoff=0.0) as c:
        with pytest.raises(ServiceUnavailable):
            c.health()
    assert len(calls) == 3


def test_a_new_base_url_retires_the_old_connection(scripted):
    a = scripted(lambda k, head, body: ok(b'{"status": "a"}'))
    b = scripted(lambda k, head, body: ok(b'{"status": "b"}'))
    with Client(a.url, timeout=10) as c:
        assert c.health()["status"] == "a"
        old = c._wire
        c.base_url = b.url
        assert c.health()["status"] == "b"
        assert old.retired and old.sock is None and c._wire is not old
        wire = c._wire
    assert wire.retired and wire.sock is None and c._wire is None


def test_binary_answers_are_read_only(daemon, paths):
    """The answer's arrays are views of its buffer: read-only on both paths
    (forces, the tangent's values, the pressure)."""
    scene = json.loads((paths.examples / "two_disks.json").read_text())
    for wire in (True, False):
        with Client(daemon.base, timeout=60, wire=wire) as c, c.session(scene) as s:
            res = s.contact(outputs=["forces", "stiffness", "pressure"])
            assert res.raw == {} and res.summary.contacts > 0
            arrays = [res.force_array(), res.stiffness_triplets()[2]] + [res.pressure[i] for i in res.pressure]
            assert all(not a.flags.writeable for a in arrays)


def test_a_redirect_to_nowhere_is_unreachable(scripted):
    """A redirect is followed through requests; its failure reads as the
    client's own (ServiceUnavailable), not a bare requests exception."""
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    dead = s.getsockname()[1]
    s.close()
    srv = scripted(lambda k, head, body: f"HTTP/1.1 307 Temporary Redirect\r\nLocation: http://127.0.0.1:{dead}/v1/"
                                         "health\r\nContent-Length: 0\r\n\r\n".encode())
    with Client(srv.url, timeout=5, retries=0) as c:
        with pytest.raises(ServiceUnavailable):
            c.health()


@pytest.mark.parametrize("answer", [
    b"HTTP/1.1 200 OK\r\nTransfer-Encoding: chunked\r\n\r\n-5\r\n{\"status\": \"ok\"}\r\n0\r\n\r\n",
    b"HTTP/1.1 200 OK\r\nTransfer-Encoding: chunked\r\n\r\n0x10\r\n{\"status\": \"ok\"}\r\n0\r\n\r\n",
    b"HTTP/1.1 200 OK\r\nContent-Length: -5\r\n\r\n{\"status\": \"ok\"}",
    b"HTTP/1.1 200 OK\r\nContent-Length: +16\r\n\r\n{\"status\": \"ok\"}",
    b"HTTP/1.1 200 OK\r\nContent-Length: 16, 17\r\n\r\n{\"status\": \"ok\"}",
])
def test_bad_framing_is_refused(scripted, answer):
    """A chunk size or Content-Length that is not plain digits (a negative
    size would have cut the body from the wrong end) is the answer cut."""
    srv = scripted(lambda k, head, body: (answer, "close"))
    with Client(srv.url, timeout=10, retries=0) as c:
        with pytest.raises(ServiceUnavailable):
            c.health()

"""--max-memory: one budget for the bodies in flight and the estimated peak of
the work they start. Past it: 503 with Retry-After (others hold the room), or
413 when a request alone needs more than the budget; never a 500."""
import json
import math
import socket
import time

import requests

from conftest import settled_health, start_daemon

HEAD = "POST /v1/contact HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\n"


def _health(d):
    return requests.get(d.url("/v1/health"), timeout=10).json()


def _zeros(n):
    """A scene-shaped document whose JSON tree is as large as it gets per byte."""
    return ('{"bodies":[{"id":0,"nodes":[' + ",".join(["[0,0]"] * n) + "]}]}").encode()


def test_a_request_that_alone_needs_more_is_413(paths, tmp_path):
    d = start_daemon(paths.bin / "ntscontactd", tmp_path / "d.log", "--max-memory", "16M")
    try:
        body = _zeros(50_000)  # 300 kB of JSON, about 17 MB of tree
        r = requests.post(d.url("/v1/contact"), data=body, headers={"Content-Type": "application/json"}, timeout=10)
        assert r.status_code == 413, r.text
        assert r.json()["error"]["code"] == "payload_too_large"
        assert "--max-memory" in r.json()["error"]["message"]
        # An announced body past the budget is refused before it is read.
        s = socket.create_connection(("127.0.0.1", d.port), timeout=10)
        s.sendall((HEAD + f"Content-Length: {20 << 20}\r\n\r\n").encode())
        assert s.recv(4096).startswith(b"HTTP/1.1 413")
        s.close()
        # A small scene still fits, and the budget is given back afterwards.
        ok = requests.post(d.url("/v1/contact"), data=(paths.examples / "two_disks.json").read_bytes(),
                           headers={"Content-Type": "application/json"}, timeout=10)
        assert ok.status_code == 200
        h = settled_health(d)
        assert h["memory"]["budget_bytes"] == 16 << 20
        assert h["memory"]["in_use_bytes"] == 0
    finally:
        assert d.stop() == 0


def test_bodies_in_flight_share_the_budget(paths, tmp_path):
    """The bytes received count, as they arrive: two uploads of 15 MiB that
    have sent 14 MiB hold 28 MiB of a 40 MiB budget, and a third that sends
    its 15 MiB outgrows the room left: 503 with Retry-After."""
    d = start_daemon(paths.bin / "ntscontactd", tmp_path / "d.log", "--max-memory", "40M", "--timeout", "60")
    held = []
    try:
        for _ in range(2):  # two uploads of 15 MiB announced, 14 MiB sent, not finished
            s = socket.create_connection(("127.0.0.1", d.port), timeout=30)
            s.sendall((HEAD + f"Content-Length: {15 << 20}\r\n\r\n").encode() + b'{"bodies": [' + b" " * (14 << 20))
            held.append(s)
        deadline = time.monotonic() + 60
        while _health(d)["memory"]["in_use_bytes"] < 28 << 20 and time.monotonic() < deadline:
            time.sleep(0.02)
        in_use = _health(d)["memory"]["in_use_bytes"]
        assert 28 << 20 <= in_use <= 30 << 20, in_use  # what they sent, at most what they announced
        # The third finds no room for its bytes: 503, retry later.
        s = socket.create_connection(("127.0.0.1", d.port), timeout=30)
        try:
            s.sendall((HEAD + f"Content-Length: {15 << 20}\r\n\r\n").encode() + b" " * (15 << 20))
            head = s.recv(4096)
        except OSError:
            head = b""
        s.close()
        assert head.startswith(b"HTTP/1.1 503"), head[:100]
        assert b"Retry-After: 1" in head
        assert b'"overloaded"' in head or b"overloaded" in head
        # So does a chunked body that outgrows the room left.
        s = socket.create_connection(("127.0.0.1", d.port), timeout=10)
        s.sendall((HEAD + "Transfer-Encoding: chunked\r\n\r\n").encode())
        chunk = b" " * (1 << 20)
        try:
            for _ in range(16):
                s.sendall(b"%x\r\n" % len(chunk) + chunk + b"\r\n")
            s.sendall(b"0\r\n\r\n")
            head = s.recv(4096)
        except OSError:
            head = b""
        s.close()
        assert head.startswith(b"HTTP/1.1 503"), head[:200]
        assert _health(d)["memory"]["refused"] >= 2
    finally:
        for s in held:
            s.close()
    try:
        # given back by the uploads that were abandoned
        assert settled_health(d)["memory"]["in_use_bytes"] == 0
        r = requests.post(d.url("/v1/contact"), data=(paths.examples / "two_disks.json").read_bytes(),
                          headers={"Content-Type": "application/json"}, timeout=10)
        assert r.status_code == 200
    finally:
        assert d.stop() == 0


def _estimate(body: bytes) -> int:
    """ntsj_memory_estimate: the body plus NTSJ_BYTES_PER_VALUE (136) per value."""
    values = 1 + sum(body.count(c) for c in (b",", b":", b"[", b"{"))
    return len(body) + 136 * values


def test_a_request_reserves_its_estimate(paths, tmp_path):
    """A budget of exactly the estimate serves the request; one byte less is 413."""
    body = (paths.examples / "two_disks.json").read_bytes()
    need = _estimate(body)
    for budget, status in ((need, 200), (need - 1, 413)):
        d = start_daemon(paths.bin / "ntscontactd", tmp_path / f"d{budget}.log", "--max-memory", str(budget))
        try:
            r = requests.post(d.url("/v1/contact"), data=body, headers={"Content-Type": "application/json"},
                              timeout=60)
            assert r.status_code == status, (budget, r.text[:200])
            if status == 413:
                assert f"about {need} bytes" in r.json()["error"]["message"]
            assert settled_health(d)["memory"]["in_use_bytes"] == 0
        finally:
            assert d.stop() == 0


def test_announced_bodies_hold_nothing_until_sent(paths, tmp_path):
    """Issue 23: 192 sockets announcing 64 MiB bodies and sending nothing
    reserved 99.8% of the budget, and an honest 2 MB scene got 503. What a
    body holds is what it has sent: 24 such sockets (1.5 GiB announced, six
    times a 256 MiB budget) hold nothing, and a 2 MB scene is served."""
    d = start_daemon(paths.bin / "ntscontactd", tmp_path / "d.log", "--max-memory", "256M",
                     "--max-bytes", "64M", "--timeout", "60")
    held = []
    try:
        for _ in range(24):
            s = socket.create_connection(("127.0.0.1", d.port), timeout=30)
            s.sendall((HEAD + f"Content-Length: {64 << 20}\r\n\r\n").encode())
            held.append(s)
        second = [[1.95 + math.cos(2 * math.pi * j / 40000), math.sin(2 * math.pi * j / 40000)] for j in range(40000)]
        doc = {"options": {"penalty": 1.0},
               "bodies": [{"id": 0, "nodes": [[math.cos(2 * math.pi * j / 40000), math.sin(2 * math.pi * j / 40000)]
                                             for j in range(40000)]},
                          {"id": 1, "nodes": second}]}
        body = json.dumps(doc).encode()
        assert len(body) > 2_000_000
        r = requests.post(d.url("/v1/contact"), data=body, headers={"Content-Type": "application/json"}, timeout=120)
        assert r.status_code == 200, r.text[:200]
        assert r.json()["summary"]["contacts"] > 0
        assert _health(d)["memory"]["refused"] == 0
    finally:
        for s in held:
            s.close()
        assert d.stop() == 0

"""Clients that hold the service without doing work: headers trickled a byte
at a time (cut by --header-seconds, however often the bytes come), and a
client that leaves while its scene is evaluated (the work stops)."""
import json
import math
import socket
import threading
import time

import requests

from conftest import settled_health, start_daemon


def _trickle(port, stop, closed_at, index, period=0.2):
    """Send a request line one byte every `period` s; record when the server closed it."""
    s = socket.create_connection(("127.0.0.1", port), timeout=5)
    s.settimeout(period)
    data = b"POST /v1/contact HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\n" + b"X-Pad: " + b"a" * 4000
    t0 = time.monotonic()
    try:
        for b in data:
            if stop.is_set():
                return
            try:
                s.sendall(bytes([b]))
            except OSError:
                closed_at[index] = time.monotonic() - t0
                return
            try:
                if s.recv(1) == b"":
                    closed_at[index] = time.monotonic() - t0
                    return
            except socket.timeout:
                pass
            except OSError:
                closed_at[index] = time.monotonic() - t0
                return
    finally:
        s.close()


def _run_trickle(port, n, seconds):
    stop = threading.Event()
    closed_at = [None] * n
    threads = [threading.Thread(target=_trickle, args=(port, stop, closed_at, i)) for i in range(n)]
    for t in threads:
        t.start()
    time.sleep(seconds)
    stop.set()
    for t in threads:
        t.join(10)
    return closed_at


def test_trickled_headers_are_cut_by_the_header_deadline(paths, tmp_path):
    d = start_daemon(paths.bin / "ntscontactd", tmp_path / "d.log", "--header-seconds", "1", "--timeout", "30",
                     "--max-connections", "20", "--max-per-client", "100")
    try:
        stop = threading.Event()
        closed_at = [None] * 10
        threads = [threading.Thread(target=_trickle, args=(d.port, stop, closed_at, i)) for i in range(10)]
        for t in threads:
            t.start()
        # Every trickler is cut, though it sends a byte every 0.2 s (each would
        # take 800 s to send its headers), and none before its second is up.
        # How soon after it the daemon gets to it is the machine's business: a
        # busy one is given a minute (the suite asserts no timing).
        deadline = time.monotonic() + 60
        while any(c is None for c in closed_at) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert all(c is not None and c > 0.8 for c in closed_at), closed_at
        # ... so another client gets in while they keep trying.
        r = requests.post(d.url("/v1/contact"), data=(paths.examples / "two_disks.json").read_bytes(),
                          headers={"Content-Type": "application/json"}, timeout=10)
        assert r.status_code == 200
        assert requests.get(d.url("/v1/health"), timeout=10).json()["header_timeouts"] >= 10
        stop.set()
        for t in threads:
            t.join(10)
    finally:
        assert d.stop() == 0
    assert "within --header-seconds 1" in d.log()


def test_without_the_header_deadline_a_trickler_stays(paths, tmp_path):
    """The control: with --header-seconds 0 the same trickle holds its connection."""
    d = start_daemon(paths.bin / "ntscontactd", tmp_path / "d.log", "--header-seconds", "0", "--timeout", "30")
    try:
        closed_at = _run_trickle(d.port, 2, 2.0)
        assert closed_at == [None, None]
    finally:
        assert d.stop() == 0


def test_an_idle_keep_alive_connection_is_served_within_the_deadline(paths, tmp_path):
    d = start_daemon(paths.bin / "ntscontactd", tmp_path / "d.log", "--header-seconds", "1")
    try:
        with requests.Session() as http:
            for _ in range(4):  # requests on one connection, 0.4 s apart: each gets its own second
                assert http.get(d.url("/v1/health"), timeout=10).status_code == 200
                time.sleep(0.4)
    finally:
        assert d.stop() == 0


def _slow_scene():
    """A brute-force search over 40,000 nodes: seconds of work."""
    bodies = []
    for k in range(100):
        ring = [[2.0 * (k % 10) + 1.0 + 0.99 * math.cos(2 * math.pi * j / 400),
                 2.0 * (k // 10) + 1.0 + 0.99 * math.sin(2 * math.pi * j / 400)] for j in range(400)]
        bodies.append({"id": k, "nodes": ring})
    return json.dumps({"options": {"penalty": 1.0, "search": "brute_force"}, "bodies": bodies}).encode()


def _evaluating(d):
    return requests.get(d.url("/v1/health"), timeout=10).json()["evaluations_running"]


def test_the_work_of_a_client_that_left_stops(paths, tmp_path):
    body = _slow_scene()
    d = start_daemon(paths.bin / "ntscontactd", tmp_path / "d.log", "--threads", "1")
    try:
        # The control: the whole evaluation is answered.
        r = requests.post(d.url("/v1/contact"), data=body, headers={"Content-Type": "application/json"}, timeout=300)
        assert r.status_code == 200
        # A client sends it, then leaves while it is evaluated.
        s = socket.create_connection(("127.0.0.1", d.port), timeout=5)
        s.sendall(b"POST /v1/contact HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\n"
                  + f"Content-Length: {len(body)}\r\n\r\n".encode() + body)
        deadline = time.monotonic() + 10
        while _evaluating(d) == 0 and time.monotonic() < deadline:
            time.sleep(0.02)
        assert _evaluating(d) == 1
        left = time.monotonic()
        s.close()
        while _evaluating(d) > 0 and time.monotonic() < left + 300:
            time.sleep(0.02)
        # The work stopped inside the core (which asks every 1024 slaves):
        # the evaluation ended as cancelled because the client left, not by
        # finishing (client_left counts only that).
        health = settled_health(d)
        assert health["evaluations_running"] == 0
        assert health["client_left"] == 1
    finally:
        assert d.stop() == 0
    assert "client_left" in d.log()

"""Every terminating signal drains like SIGTERM (within --drain-seconds), and
SIGHUP reopens --log-file instead of killing the daemon; one client cannot
take every connection (--max-per-client)."""
import json
import signal
import socket
import threading
import time

import pytest
import requests

from conftest import start_daemon


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT, signal.SIGQUIT, signal.SIGUSR1, signal.SIGUSR2,
                                 signal.SIGALRM])
def test_terminating_signals_drain(paths, tmp_path, sig):
    d = start_daemon(paths.bin / "ntscontactd", tmp_path / "d.log", "--threads", "1")
    # A slow request in flight: a brute-force search of 40 x 400 nodes.
    import math
    bodies = [{"id": k, "nodes": [[2.0 * (k % 8) + math.cos(6.2831853 * j / 400), 2.0 * (k // 8) +
                                   math.sin(6.2831853 * j / 400)] for j in range(400)]} for k in range(40)]
    doc = {"options": {"penalty": 1.0, "search": "brute_force"}, "bodies": bodies}
    result = {}
    t = threading.Thread(target=lambda: result.setdefault(
        "r", requests.post(d.url("/v1/contact"), json=doc, timeout=60)))
    t.start()
    time.sleep(0.15)
    assert d.stop(sig) == 0          # drained, not killed
    t.join()
    assert result["r"].status_code == 200
    assert f"{signal.Signals(sig).name}: stopping, " in d.log()


def test_drain_deadline_abandons(paths, tmp_path):
    d = start_daemon(paths.bin / "ntscontactd", tmp_path / "d.log", "--threads", "1", "--drain-seconds", "0")
    import math
    bodies = [{"id": k, "nodes": [[2.0 * (k % 10) + math.cos(6.2831853 * j / 600), 2.0 * (k // 10) +
                                   math.sin(6.2831853 * j / 600)] for j in range(600)]} for k in range(100)]
    doc = {"options": {"penalty": 1.0, "search": "brute_force"}, "bodies": bodies}
    def post():
        try:
            requests.post(d.url("/v1/contact"), json=doc, timeout=120)
        except requests.RequestException:
            pass  # the daemon left with the request unanswered: what this test wants

    t = threading.Thread(target=post, daemon=True)
    t.start()
    time.sleep(0.5)
    assert d.stop(signal.SIGTERM, timeout=30) == 1  # the request was still running at the deadline
    assert "--drain-seconds passed" in d.log()


def test_sighup_reopens_the_log(paths, tmp_path):
    log = tmp_path / "ntscontactd.log"
    d = start_daemon(paths.bin / "ntscontactd", tmp_path / "stderr.log", "--log-file", str(log))
    assert requests.get(d.url("/v1/health"), timeout=10).status_code == 200
    time.sleep(0.1)
    rotated = tmp_path / "ntscontactd.log.1"
    log.rename(rotated)
    d.proc.send_signal(signal.SIGHUP)
    time.sleep(0.3)
    assert d.proc.poll() is None  # alive
    assert requests.get(d.url("/v1/health"), timeout=10).status_code == 200
    time.sleep(0.1)
    assert "GET /v1/health" in rotated.read_text()
    assert "SIGHUP: log reopened" in log.read_text() and "GET /v1/health" in log.read_text()
    assert d.stop() == 0


def test_one_client_cannot_take_every_connection(paths, tmp_path):
    """Past --max-per-client from one address, each new connection from it
    cuts that address's slowest (here: the longest silent): the client's own
    new requests are served, and it never holds more than its share."""
    d = start_daemon(paths.bin / "ntscontactd", tmp_path / "d.log", "--max-per-client", "4")
    held = [socket.create_connection(("127.0.0.1", d.port), timeout=30) for _ in range(12)]
    try:
        health = requests.get(d.url("/v1/health"), timeout=30).json()  # a 13th: served, it cuts the 9th
        assert health["connections_open"] <= 4
        for s in held[:9]:  # the oldest nine were cut: each sees its end of stream
            assert s.recv(1) == b""
    finally:
        for s in held:
            s.close()
    h = requests.get(d.url("/v1/health"), timeout=30).json()  # (may cut one the daemon has not seen closed)
    assert h["shed"] >= 9 and h["connections_open"] <= 4
    assert d.stop() == 0


def test_sighup_reloads_the_token_file(paths, tmp_path):
    """SIGHUP reads --token-file again: a token taken out of it is refused
    (revoking a token needed a restart), one put in is taken. A file that
    cannot be loaded keeps the tokens loaded before, and the log says why.
    Requests running meanwhile see the old list or the new, whole."""
    tokens = tmp_path / "tokens"
    tokens.write_text("token-a\n")
    d = start_daemon(paths.bin / "ntscontactd", tmp_path / "d.log", "--token-file", str(tokens))

    def status(token):
        return requests.get(d.url("/v1/openapi.json"), headers={"Authorization": f"Bearer {token}"},
                            timeout=10).status_code

    def until(predicate, what, within_s=60.0):  # a generous deadline: the signal is handled in its own time
        deadline = time.monotonic() + within_s
        while not predicate():
            assert time.monotonic() < deadline, what
            time.sleep(0.05)

    try:
        assert status("token-a") == 200 and status("token-b") == 401
        tokens.write_text("# token-a revoked\ntoken-b\n")
        d.proc.send_signal(signal.SIGHUP)
        until(lambda: status("token-a") == 401, "token-a still taken after SIGHUP")
        assert status("token-b") == 200
        # A file that cannot be loaded: the tokens stay, the log says why.
        tokens.write_text("# nothing\n")
        d.proc.send_signal(signal.SIGHUP)
        until(lambda: "holds no token" in d.log(), "no word of the empty token file")
        tokens.unlink()
        d.proc.send_signal(signal.SIGHUP)
        until(lambda: "cannot open it" in d.log(), "no word of the missing token file")
        assert status("token-b") == 200 and status("token-a") == 401
        # Reloads while requests run: token-c is in every version of the file.
        stop, seen = threading.Event(), []

        def ask():
            while not stop.is_set():
                r = requests.get(d.url("/v1/health"), headers={"Authorization": "Bearer token-c"}, timeout=10)
                seen.append((r.status_code, "build" in r.json()))

        tokens.write_text("token-c\n")
        d.proc.send_signal(signal.SIGHUP)
        until(lambda: status("token-c") == 200, "token-c not taken after SIGHUP")
        threads = [threading.Thread(target=ask) for _ in range(2)]
        for t in threads:
            t.start()
        for k in range(40):
            tmp = tmp_path / "tokens.new"
            tmp.write_text("token-c\ntoken-d\n" if k % 2 else "token-e\n# x\ntoken-c\n")
            tmp.replace(tokens)
            d.proc.send_signal(signal.SIGHUP)
            time.sleep(0.01)
        stop.set()
        for t in threads:
            t.join()
        assert seen and all(x == (200, True) for x in seen), [x for x in seen if x != (200, True)][:5]
    finally:
        assert d.stop() == 0
    log = d.log()
    assert "token-a" not in log and "token-b" not in log and "token-c" not in log  # never a token in the log
    assert "SIGHUP: log reopened" in log

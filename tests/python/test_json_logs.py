"""--log-format json: every log line is one JSON object, whatever a client put
in its request line."""
import json
import socket

import pytest
import requests

from conftest import start_daemon


def test_every_line_is_a_json_object(paths, tmp_path):
    d = start_daemon(paths.bin / "ntscontactd", tmp_path / "d.log", "--log-format", "json")
    try:
        assert requests.post(d.url("/v1/contact"), data=(paths.examples / "two_disks.json").read_bytes(),
                             headers={"Content-Type": "application/json"}, timeout=10).status_code == 200
        # A path with a quote, a backslash, a control byte and a byte that is not UTF-8, percent-encoded.
        s = socket.create_connection(("127.0.0.1", d.port), timeout=10)
        s.sendall(b"GET /a%22b%5Cc%01d%FFe HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n")
        assert s.recv(4096).startswith(b"HTTP/1.1 404")
        s.close()
        s = socket.create_connection(("127.0.0.1", d.port), timeout=10)  # a method that is not ASCII
        s.sendall(b"G\xe9T /v1/health HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n")
        assert s.recv(4096).startswith(b"HTTP/1.1 405")
        s.close()
    finally:
        assert d.stop() == 0
    lines = [json.loads(line) for line in d.log().splitlines() if line.strip()]
    assert lines and all({"time", "level", "event"} <= set(x) for x in lines)
    requests_logged = [x for x in lines if x["event"] == "request"]
    ok = [x for x in requests_logged if x["path"] == "/v1/contact"]
    assert len(ok) == 1 and ok[0]["status"] == 200 and ok[0]["code"] == "ok" and ok[0]["bytes_out"] > 0
    odd = [x for x in requests_logged if x["status"] == 404]
    assert len(odd) == 1 and odd[0]["path"] == '/a"b\\c\x01d\xffe'
    assert [x["method"] for x in requests_logged if x["status"] == 405] == ["G\xe9T"]
    assert any(x["event"] == "message" and "stopped after" in x["message"] for x in lines)


def test_a_log_format_must_be_known(paths):
    import subprocess
    r = subprocess.run([str(paths.bin / "ntscontactd"), "--log-format", "xml"], capture_output=True, timeout=10)
    assert r.returncode == 2 and b"text or json" in r.stderr


@pytest.mark.parametrize("fmt", ["text"])
def test_text_stays_the_default(paths, tmp_path, fmt):
    d = start_daemon(paths.bin / "ntscontactd", tmp_path / "d.log", "--log-format", fmt)
    try:
        requests.get(d.url("/v1/health"), timeout=10)
    finally:
        assert d.stop() == 0
    assert "GET /v1/health 200 ok" in d.log()


def test_text_lines_escape_what_a_client_sent(paths, tmp_path):
    """The text log is plain ASCII whatever a request line holds: control bytes,
    bytes over 0x7f (raw or percent-encoded), the backslash and a decoded space
    are written \\xNN (they were written raw, or as '?')."""
    d = start_daemon(paths.bin / "ntscontactd", tmp_path / "d.log")
    try:
        for raw in (b"GET /x%01y%FFz%20w%5Cv\xc3\xa9\x7f HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n",
                    b"G\xe9T /v1/health HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n"):
            s = socket.create_connection(("127.0.0.1", d.port), timeout=10)
            s.sendall(raw)
            assert s.recv(4096).startswith(b"HTTP/1.1 40")
            s.close()
    finally:
        assert d.stop() == 0
    log = d.log_path.read_bytes()
    assert all(b == 0x0A or 0x20 <= b < 0x7F for b in log), log
    text = log.decode("ascii")
    assert " GET /x\\x01y\\xffz\\x20w\\x5cv\\xc3\\xa9\\x7f 404 not_found " in text, text
    assert " G\\xe9T /v1/health 405 method_not_allowed " in text, text

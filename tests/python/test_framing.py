"""HTTP framing (F9-F11 in docs/reliability.md): ambiguous framing refused
with the error schema, a Host allow-list, and what libmicrohttpd 0.9.75 still
answers on its own (a bad Content-Length: refused, in its own words)."""
import json

import jsonschema

from conftest import raw_response, start_daemon


def test_content_length_with_chunked_is_refused(paths, tmp_path, schemas):
    body = (paths.examples / "two_disks.json").read_bytes()
    d = start_daemon(paths.bin / "ntscontactd", tmp_path / "d.log")
    try:
        raw = (b"POST /v1/contact HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\nContent-Length: 5\r\n"
               b"Transfer-Encoding: chunked\r\nConnection: close\r\n\r\n" + b"%x\r\n" % len(body) + body + b"\r\n0\r\n\r\n")
        status, _, answer = raw_response(d.port, raw)
        doc = json.loads(answer)
        assert status == 400
        assert doc["error"]["code"] == "bad_request" and "ambiguous" in doc["error"]["message"]
        jsonschema.validate(doc, schemas["error"])
        # Either framing alone is served.
        for framing in (b"Content-Length: %d\r\n\r\n" % len(body) + body,
                        b"Transfer-Encoding: chunked\r\n\r\n" + b"%x\r\n" % len(body) + body + b"\r\n0\r\n\r\n"):
            status, _, answer = raw_response(d.port, b"POST /v1/contact HTTP/1.1\r\nHost: x\r\n"
                                                b"Content-Type: application/json\r\nConnection: close\r\n" + framing)
            assert status == 200, answer[:100]
    finally:
        assert d.stop() == 0


def test_a_bad_content_length_is_refused(paths, tmp_path):
    """libmicrohttpd answers this one itself (HTML, and 0.9.75 writes its status
    line twice): never evaluated, the connection closed."""
    d = start_daemon(paths.bin / "ntscontactd", tmp_path / "d.log")
    try:
        status, _, body = raw_response(d.port, b"POST /v1/contact HTTP/1.1\r\nHost: x\r\n"
                                          b"Content-Type: application/json\r\nContent-Length: 1x\r\n\r\n{}")
        assert status == 400 and b"summary" not in body
    finally:
        assert d.stop() == 0


def test_allow_host(paths, tmp_path, schemas):
    d = start_daemon(paths.bin / "ntscontactd", tmp_path / "d.log", "--allow-host", "127.0.0.1",
                     "--allow-host", "contact.example.org")
    try:
        for host, status in ((b"127.0.0.1:%d" % d.port, 200), (b"contact.example.org", 200),
                             (b"CONTACT.example.org:80", 200), (b"attacker.example", 403),
                             (b"127.0.0.1.attacker.example", 403), (b"127.0.0.10", 403)):
            got, _, body = raw_response(d.port, b"GET /v1/health HTTP/1.1\r\nHost: " + host +
                                        b"\r\nConnection: close\r\n\r\n")
            assert got == status, (host, body[:80])
            if status == 403:
                doc = json.loads(body)
                assert doc["error"]["code"] == "forbidden"
                jsonschema.validate(doc, schemas["error"])
        assert raw_response(d.port, b"GET /v1/health HTTP/1.0\r\n\r\n")[0] == 403  # no Host at all
    finally:
        assert d.stop() == 0

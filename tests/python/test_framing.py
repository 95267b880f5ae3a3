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


def exchange(port, data, timeout=20):
    """Send raw bytes, read until the daemon closes: every byte it answered.
    A daemon that keeps the connection open fails the test (socket timeout)."""
    import socket
    from conftest import recv_all
    with socket.create_connection(("127.0.0.1", port), timeout=timeout) as s:
        s.sendall(data)
        return recv_all(s)


def one_bad_request(out, schemas, *words):
    """Exactly one answer: a 400 bad_request in the error schema whose message has `words`."""
    assert out.count(b"HTTP/1.1 ") == 1, out
    head, _, body = out.partition(b"\r\n\r\n")
    assert head.startswith(b"HTTP/1.1 400 ") and b"\r\nConnection: close" in head, out
    doc = json.loads(body)
    jsonschema.validate(doc, schemas["error"])
    assert doc["error"]["code"] == "bad_request", doc
    for w in words:
        assert w in doc["error"]["message"], doc


def test_a_header_name_must_be_a_token(paths, tmp_path, schemas):
    """`Transfer-Encoding : chunked` (a space before the colon) was not a
    Transfer-Encoding to libmicrohttpd 0.9.75: the request was taken without a
    body and the chunks as the next request (two answers, a smuggled request).
    Any header name with whitespace or a character outside RFC 9110's token is
    refused with one 400 and a close."""
    d = start_daemon(paths.bin / "ntscontactd", tmp_path / "d.log")
    try:
        smuggled = b"GET /v1/health HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n"  # the "body"
        for name in (b"Transfer-Encoding ", b"Transfer-Encoding\t", b"Content-Length ", b"Foo\t", b"Fo(o",
                     b"F\xc3\xa9"):
            value = b"chunked" if name.startswith(b"Transfer") else b"1" if name.startswith(b"Content") else b"y"
            out = exchange(d.port, b"POST /v1/contact HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\n" +
                           name + b": " + value + b"\r\n\r\n" + smuggled)
            one_bad_request(out, schemas, "header name")
        # An empty name, first: refused too. (Later, libmicrohttpd 0.9.75 takes
        # that line for the end of the headers: docs/reliability.md, "Framing".)
        out = exchange(d.port, b"POST /v1/contact HTTP/1.1\r\n: y\r\nHost: x\r\nContent-Type: application/json\r\n"
                       b"\r\n" + smuggled)
        one_bad_request(out, schemas, "header name")
        # A header name that is a token is served, whatever its case.
        out = exchange(d.port, b"GET /v1/health HTTP/1.1\r\nHost: x\r\nX-Odd_Name.1~!: y\r\nconnection: close\r\n\r\n")
        assert out.startswith(b"HTTP/1.1 200 ") and out.count(b"HTTP/1.1 ") == 1, out
    finally:
        assert d.stop() == 0
    assert "bad_header" not in d.log()  # the refusal's code in the log is bad_request
    assert d.log().count(" POST /v1/contact 400 bad_request ") == 7


def test_headers_read_once_are_refused_twice(paths, tmp_path, schemas):
    """libmicrohttpd keeps every copy of a header and its lookup gives the
    first: two Authorization, Host, Origin, Content-Length or
    Transfer-Encoding headers (which a proxy in front may read otherwise) get
    one 400 naming the header, and a close."""
    body = (paths.examples / "two_disks.json").read_bytes()
    chunked = b"%x\r\n" % len(body) + body + b"\r\n0\r\n\r\n"
    d = start_daemon(paths.bin / "ntscontactd", tmp_path / "d.log", "--allow-origin", "https://a.example",
                     "--allow-origin", "https://b.example")
    try:
        post = b"POST /v1/contact HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\n"
        cases = {
            "Authorization": post + b"Authorization: Bearer a\r\nauthorization: Bearer b\r\nContent-Length: %d\r\n\r\n"
                             % len(body) + body,
            "Host": b"GET /v1/health HTTP/1.1\r\nHost: x\r\nHOST: y\r\n\r\n",
            "Origin": b"GET /v1/health HTTP/1.1\r\nHost: x\r\nOrigin: https://a.example\r\n"
                      b"Origin: https://b.example\r\n\r\n",
            "Content-Length": post + b"Content-Length: 5\r\nContent-Length: %d\r\n\r\n" % len(body) + body,
            "Content-Length ": post + b"Content-Length: %d\r\nContent-Length: %d\r\n\r\n" % (len(body), len(body)) + body,
            "Transfer-Encoding": post + b"Transfer-Encoding: chunked\r\nTransfer-Encoding: chunked\r\n\r\n" + chunked,
        }
        for name, raw in cases.items():
            one_bad_request(exchange(d.port, raw), schemas, name.strip(), "twice")
        # Once each: served.
        out = exchange(d.port, post + b"Authorization: Bearer a\r\nOrigin: https://a.example\r\nConnection: close\r\n"
                       b"Content-Length: %d\r\n\r\n" % len(body) + body)
        assert out.startswith(b"HTTP/1.1 200 ") and out.count(b"HTTP/1.1 ") == 1, out[:200]
        metrics = exchange(d.port, b"GET /metrics HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n").decode()
        assert 'ntscontactd_refusals_total{reason="bad_header"} 6' in metrics, metrics
    finally:
        assert d.stop() == 0


def test_transfer_codings_other_than_chunked_are_refused(paths, tmp_path, schemas):
    """libmicrohttpd 0.9.75 takes a Transfer-Encoding other than `chunked` as
    a body that lasts until the connection closes: the request hung until
    --timeout. RFC 9112 6.3: a request whose final coding is not chunked
    cannot be framed, 400 and close. So is a Transfer-Encoding in HTTP/1.0.
    `TE` (the codings the client accepts in an answer) is no framing: served."""
    body = (paths.examples / "two_disks.json").read_bytes()
    chunked = b"%x\r\n" % len(body) + body + b"\r\n0\r\n\r\n"
    d = start_daemon(paths.bin / "ntscontactd", tmp_path / "d.log")
    try:
        for coding in (b"gzip", b"gzip, chunked", b"chunked, gzip", b"identity", b"chunked;x=1"):
            out = exchange(d.port, b"POST /v1/contact HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\n"
                           b"Transfer-Encoding: " + coding + b"\r\n\r\n" + chunked)
            one_bad_request(out, schemas, "Transfer-Encoding")
        out = exchange(d.port, b"GET /v1/health HTTP/1.1\r\nHost: x\r\nTransfer-Encoding: gzip\r\n\r\n")
        one_bad_request(out, schemas, "Transfer-Encoding")
        out = exchange(d.port, b"POST /v1/contact HTTP/1.0\r\nHost: x\r\nContent-Type: application/json\r\n"
                       b"Transfer-Encoding: chunked\r\n\r\n" + chunked)
        one_bad_request(out, schemas, "HTTP/1.0")
        for te in (b"gzip", b"trailers"):
            out = exchange(d.port, b"POST /v1/contact HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\n"
                           b"TE: " + te + b"\r\nConnection: close\r\nContent-Length: %d\r\n\r\n" % len(body) + body)
            assert out.startswith(b"HTTP/1.1 200 ") and out.count(b"HTTP/1.1 ") == 1, out[:200]
        out = exchange(d.port, b"POST /v1/contact HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\n"
                       b"Transfer-Encoding: Chunked\r\nConnection: close\r\n\r\n" + chunked)
        assert out.startswith(b"HTTP/1.1 200 ") and out.count(b"HTTP/1.1 ") == 1, out[:200]
    finally:
        assert d.stop() == 0

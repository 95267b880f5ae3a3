"""Access control of ntscontactd: bearer tokens (401 with WWW-Authenticate, a
constant-time compare), health without build details unless authenticated,
browser Origins refused unless allowed (403), and HTTPS through GnuTLS."""
import shutil
import subprocess

import pytest
import requests

ntscontact = pytest.importorskip("ntscontact")
from conftest import start_daemon  # noqa: E402

SCENE = {"options": {"penalty": 10.0}, "bodies": [{"id": "a", "nodes": [[0, 0], [1, 0], [1, 1], [0, 1]]},
                                                  {"id": "b", "nodes": [[0.9, 0.1], [2, 0.1], [2, 0.9], [0.9, 0.9]]}]}


def test_bearer_tokens(paths, tmp_path, schemas):
    tokens = tmp_path / "tokens"
    tokens.write_text("# the service's tokens\nalpha-token-1\n\nbeta-token-2\n")
    d = start_daemon(paths.bin / "ntscontactd", tmp_path / "d.log", "--token-file", str(tokens))
    try:
        for headers in ({}, {"Authorization": "Bearer wrong"}, {"Authorization": "Basic alpha-token-1"},
                        {"Authorization": "Bearer alpha-token-1x"}, {"Authorization": "Bearer alpha-token-"}):
            r = requests.post(d.url("/v1/contact"), json=SCENE, headers=headers, timeout=10)
            assert r.status_code == 401, headers
            assert r.headers["WWW-Authenticate"].startswith("Bearer")
            assert r.json()["error"]["code"] == "unauthorized"
            r = requests.get(d.url("/v1/openapi.json"), headers=headers, timeout=10)
            assert r.status_code == 401
        for token in ("alpha-token-1", "beta-token-2"):
            r = requests.post(d.url("/v1/contact"), json=SCENE, headers={"Authorization": f"Bearer {token}"},
                              timeout=10)
            assert r.status_code == 200
        # Health: up or not for anyone, the details for the authenticated only.
        assert requests.get(d.url("/v1/health"), timeout=10).json() == {"status": "ok"}
        full = requests.get(d.url("/v1/health"), headers={"Authorization": "Bearer beta-token-2"}, timeout=10).json()
        assert "build" in full and "server" in full and full["status"] == "ok"
        # The Python client sends its token.
        with ntscontact.Client(d.base, token="alpha-token-1") as c:
            assert c.contact(SCENE).summary.contacts > 0
            with c.session(SCENE) as s:
                assert s.contact().summary.contacts > 0
        with ntscontact.Client(d.base) as c:
            with pytest.raises(ntscontact.NtsError) as e:
                c.contact(SCENE)
            assert e.value.status == 401
    finally:
        assert d.stop() == 0


def test_a_token_file_must_hold_a_token(paths, tmp_path):
    empty = tmp_path / "empty"
    empty.write_text("# nothing\n\n")
    r = subprocess.run([str(paths.bin / "ntscontactd"), "--port", "0", "--token-file", str(empty)],
                       capture_output=True, timeout=10)
    assert r.returncode == 2 and b"holds no token" in r.stderr


def test_origins(paths, tmp_path):
    d = start_daemon(paths.bin / "ntscontactd", tmp_path / "d.log", "--allow-origin", "https://app.example.org")
    try:
        r = requests.post(d.url("/v1/contact"), json=SCENE, headers={"Origin": "https://evil.example"}, timeout=10)
        assert r.status_code == 403 and r.json()["error"]["code"] == "forbidden"
        r = requests.get(d.url("/v1/health"), headers={"Origin": "null"}, timeout=10)
        assert r.status_code == 403
        r = requests.post(d.url("/v1/contact"), json=SCENE, headers={"Origin": "https://app.example.org"}, timeout=10)
        assert r.status_code == 200
        assert requests.post(d.url("/v1/contact"), json=SCENE, timeout=10).status_code == 200  # no Origin: not a browser
    finally:
        assert d.stop() == 0


@pytest.mark.skipif(shutil.which("openssl") is None, reason="needs openssl to make a certificate")
def test_https(paths, tmp_path):
    key, cert = tmp_path / "key.pem", tmp_path / "cert.pem"
    subprocess.run(["openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-keyout", str(key), "-out",
                    str(cert), "-days", "1", "-subj", "/CN=127.0.0.1", "-addext", "subjectAltName=IP:127.0.0.1"],
                   check=True, capture_output=True, timeout=60)
    d = start_daemon(paths.bin / "ntscontactd", tmp_path / "d.log", "--tls-cert", str(cert), "--tls-key", str(key))
    try:
        base = d.base.replace("http://", "https://")
        r = requests.post(base + "/v1/contact", json=SCENE, verify=str(cert), timeout=20)
        assert r.status_code == 200 and r.json()["summary"]["contacts"] > 0
        with pytest.raises(requests.exceptions.SSLError):
            requests.get(base + "/v1/health", timeout=20)  # not trusted without the certificate
        with ntscontact.Client(base, verify=str(cert)) as c:
            assert c.contact(SCENE).summary.contacts > 0
    finally:
        assert d.stop() == 0
    r = subprocess.run([str(paths.bin / "ntscontactd"), "--port", "0", "--tls-cert", str(cert)], capture_output=True,
                       timeout=10)
    assert r.returncode == 2 and b"go together" in r.stderr


APP = "https://app.example.org"
SID = "A" * 43
ROUTES = {"/v1/contact": "POST", "/v1/validate": "POST", "/v1/scenes": "POST", f"/v1/scenes/{SID}": "GET, HEAD, DELETE",
          f"/v1/scenes/{SID}/contact": "POST", "/v1/health": "GET, HEAD", "/metrics": "GET, HEAD",
          "/v1/openapi.json": "GET, HEAD", "/v1/schemas/scene": "GET, HEAD"}


def cors_headers(r):
    return {k.lower(): v for k, v in r.headers.items() if k.lower().startswith("access-control-")}


def test_cors_preflight_from_an_allowed_origin(paths, tmp_path):
    """--allow-origin let a web page's requests through, but its browser's
    preflight (OPTIONS) got 405 and no answer carried CORS headers: an allowed
    page could not use the service. Now the preflight from an allowed Origin
    gets 204 with the route's methods and the headers the service reads,
    without a token; from any other Origin, or none, 403 without CORS headers."""
    tokens = tmp_path / "tokens"
    tokens.write_text("alpha-token-1\n")
    d = start_daemon(paths.bin / "ntscontactd", tmp_path / "d.log", "--allow-origin", "https://other.example",
                     "--allow-origin", APP, "--token-file", str(tokens))
    try:
        for path, methods in ROUTES.items():
            r = requests.options(d.url(path), headers={"Origin": APP, "Access-Control-Request-Method": "POST",
                                                       "Access-Control-Request-Headers": "authorization,content-type"},
                                 timeout=10)
            assert r.status_code == 204 and r.content == b"", (path, r.status_code, r.text)
            h = cors_headers(r)
            assert h["access-control-allow-origin"] == APP, h
            assert h["access-control-allow-methods"] == methods, (path, h)
            allowed = {x.strip().lower() for x in h["access-control-allow-headers"].split(",")}
            assert allowed == {"authorization", "content-type", "accept"}, h
            assert int(h["access-control-max-age"]) > 0
            assert "Origin" in r.headers["Vary"]
            assert r.headers["Allow"] == methods + ", OPTIONS"
            assert "access-control-allow-credentials" not in h
        # A header the service does not read is not allowed (the browser then refuses).
        r = requests.options(d.url("/v1/contact"), headers={"Origin": APP, "Access-Control-Request-Method": "POST",
                                                            "Access-Control-Request-Headers": "x-custom"}, timeout=10)
        assert r.status_code == 204 and "x-custom" not in r.headers["Access-Control-Allow-Headers"].lower()
        # Any other Origin, or none: 403, no CORS headers.
        for headers in ({"Origin": "https://evil.example", "Access-Control-Request-Method": "POST"},
                        {"Origin": "null"}, {}):
            r = requests.options(d.url("/v1/contact"), headers=headers, timeout=10)
            assert r.status_code == 403 and r.json()["error"]["code"] == "forbidden", (headers, r.text)
            assert cors_headers(r) == {}, r.headers
        # No such route: 404 (the preflight tells nothing the route table does not).
        r = requests.options(d.url("/v1/nowhere"), headers={"Origin": APP}, timeout=10)
        assert r.status_code == 404
    finally:
        assert d.stop() == 0


def test_cors_headers_on_answers_to_an_allowed_origin(paths, tmp_path):
    """What an allowed page reads: every answer to its Origin carries
    Access-Control-Allow-Origin, Vary: Origin and the headers it may read
    (Location, Retry-After, every NTS-* header of a binary step)."""
    import numpy as np
    tokens = tmp_path / "tokens"
    tokens.write_text("alpha-token-1\n")
    d = start_daemon(paths.bin / "ntscontactd", tmp_path / "d.log", "--allow-origin", APP, "--token-file", str(tokens))
    page = {"Origin": APP, "Authorization": "Bearer alpha-token-1"}
    try:
        r = requests.post(d.url("/v1/contact"), json=SCENE, headers=page, timeout=10)
        assert r.status_code == 200
        assert r.headers["Access-Control-Allow-Origin"] == APP and "Origin" in r.headers["Vary"]
        exposed = {x.strip().lower() for x in r.headers["Access-Control-Expose-Headers"].split(",")}
        assert {"location", "retry-after", "nts-warnings"} <= exposed
        # The page reads a 401 too (it must know its token was refused).
        r = requests.post(d.url("/v1/contact"), json=SCENE, headers={"Origin": APP}, timeout=10)
        assert r.status_code == 401 and r.headers["Access-Control-Allow-Origin"] == APP
        # A session: its Location, and every header of a binary step, are exposed.
        r = requests.post(d.url("/v1/scenes"), json=SCENE, headers=page, timeout=10)
        assert r.status_code == 201 and r.headers["Access-Control-Allow-Origin"] == APP
        location = r.headers["Location"]
        pos = np.array([n for b in SCENE["bodies"] for n in b["nodes"]], dtype="<f8")
        r = requests.post(d.url(location + "/contact"), data=pos.tobytes(),
                          headers={**page, "Content-Type": "application/octet-stream",
                                   "Accept": "application/octet-stream"}, timeout=10)
        assert r.status_code == 200, r.text
        nts = {k.lower() for k in r.headers if k.lower().startswith("nts-")}
        assert len(nts) >= 10 and nts <= exposed, nts - exposed
        # No Origin (not a browser): no CORS headers, but Vary (a cache keeps both answers apart).
        r = requests.post(d.url("/v1/contact"), json=SCENE, headers={"Authorization": "Bearer alpha-token-1"},
                          timeout=10)
        assert r.status_code == 200 and cors_headers(r) == {} and "Origin" in r.headers["Vary"]
    finally:
        assert d.stop() == 0

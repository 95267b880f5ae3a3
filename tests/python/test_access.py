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

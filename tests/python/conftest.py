"""Shared pytest fixtures: where the repository, the build, the binaries, the
example scenes and the JSON Schemas are. The build directory is $NTS_BUILD_DIR
(default <repo>/build). Keep this file small and generic; append fixtures."""
import json
import os
import pathlib
import types

import pytest

REPO = pathlib.Path(__file__).resolve().parents[2]
BUILD = pathlib.Path(os.environ.get("NTS_BUILD_DIR", str(REPO / "build"))).resolve()
CLI = BUILD / "bin" / "ntscontact"


def run_cli_json(doc, *flags):
    """The CLI on a scene document given on stdin: its JSON answer (exit 0 asserted)."""
    import subprocess
    r = subprocess.run([str(CLI), *flags, "-"], input=json.dumps(doc).encode(), capture_output=True, timeout=60)
    assert r.returncode == 0, r.stderr.decode()
    return json.loads(r.stdout)


@pytest.fixture(scope="session")
def paths():
    """paths.repo, .build, .bin, .cli (build/bin/ntscontact), .examples, .schemas."""
    return types.SimpleNamespace(
        repo=REPO,
        build=BUILD,
        bin=BUILD / "bin",
        cli=BUILD / "bin" / "ntscontact",
        examples=REPO / "examples",
        schemas=REPO / "schemas",
    )


@pytest.fixture(scope="session")
def schemas(paths):
    """The JSON Schemas by short name: schemas["scene"], ["result"], ["error"]."""
    return {name: json.loads((paths.schemas / f"{name}.schema.json").read_text())
            for name in ("scene", "result", "error", "session")}


# ------------------------------------------------------------ ntscontactd
# The daemon on a free port (--port 0: it prints "ntscontactd listening on
# HOST:PORT" as its first line on stdout), stopped by its pid with SIGTERM.
# Its stderr (one log line per request) goes to a file, never to a pipe nobody
# reads.
import selectors  # noqa: E402
import shutil  # noqa: E402
import signal  # noqa: E402
import subprocess  # noqa: E402


class Daemon:
    """A running ntscontactd: .proc, .port, .base ("http://127.0.0.1:PORT"),
    .log_path; url(path), log(), stop(sig) -> exit status."""

    def __init__(self, proc, port, log_path):
        self.proc, self.port, self.log_path = proc, port, log_path
        self.base = f"http://127.0.0.1:{port}"

    def url(self, path):
        return self.base + path

    def log(self):
        return self.log_path.read_text(errors="replace")

    def stop(self, sig=signal.SIGTERM, timeout=60):
        if self.proc.poll() is None:
            os.kill(self.proc.pid, sig)
        try:
            return self.proc.wait(timeout=timeout)
        finally:
            if self.proc.poll() is None:
                self.proc.kill()
                self.proc.wait()
            if self.proc.stdout:
                self.proc.stdout.close()


def start_daemon(binary, log_path, *args, timeout=20):
    """Start `binary --port 0 $NTS_DAEMON_ARGS ARGS`, wait for its address line, return a Daemon."""
    if not pathlib.Path(binary).exists():
        pytest.fail(f"{binary} is not built (NTS_BUILD_DIR={BUILD})")
    log = open(log_path, "wb")
    # NTS_DAEMON_ARGS: extra flags for every daemon of the tests (e.g. "--threads 1").
    extra = os.environ.get("NTS_DAEMON_ARGS", "").split()
    proc = subprocess.Popen([str(binary), "--port", "0", *extra, *map(str, args)],
                            stdout=subprocess.PIPE, stderr=log, stdin=subprocess.DEVNULL)
    log.close()
    sel = selectors.DefaultSelector()
    sel.register(proc.stdout, selectors.EVENT_READ)
    line = b""
    if sel.select(timeout):
        line = proc.stdout.readline()
    sel.close()
    text = line.decode(errors="replace").strip()
    if not text.startswith("ntscontactd listening on "):
        proc.kill()
        proc.wait()
        pytest.fail(f"ntscontactd did not start: {text!r}\n{pathlib.Path(log_path).read_text(errors='replace')}")
    return Daemon(proc, int(text.rsplit(":", 1)[1]), pathlib.Path(log_path))


import time  # noqa: E402

import requests  # noqa: E402


def settled_health(d, within_s=60.0, **kw):
    """The daemon's /v1/health document once every request before this call
    has completed on the server's side: counted (served, metrics) and its
    memory given back. That happens when a request completes, which may be
    just after the client has read its answer. The document counts the
    requests in flight (itself included) under the same lock as the
    counters. Fails if they have not completed within `within_s` (generous:
    a busy machine may take its time, and it costs nothing when settled)."""
    deadline = time.monotonic() + within_s
    while True:
        h = requests.get(d.url("/v1/health"), timeout=10, **kw).json()
        if h["requests_in_flight"] == 1 and h["memory"]["in_use_bytes"] == 0:
            return h
        if time.monotonic() > deadline:
            pytest.fail(f"requests still in flight after {within_s} s: {h}")
        time.sleep(0.02)


import socket  # noqa: E402


def recv_all(sock, limit=1 << 22):
    """Read until the peer closes (or `limit` bytes). Connection resets count as close."""
    out = b""
    try:
        while len(out) < limit:
            chunk = sock.recv(65536)
            if not chunk:
                break
            out += chunk
    except (ConnectionResetError, BrokenPipeError):
        pass
    return out


def raw_response(port, data, timeout=20):
    """Send raw bytes, read until close, return (status, headers, body)."""
    with socket.create_connection(("127.0.0.1", port), timeout=timeout) as s:
        s.sendall(data)
        out = recv_all(s)
    head, _, body = out.partition(b"\r\n\r\n")
    lines = head.split(b"\r\n")
    status = int(lines[0].split()[1]) if lines and lines[0].startswith(b"HTTP/1.") else 0
    headers = {}
    for line in lines[1:]:
        k, _, v = line.partition(b":")
        headers[k.strip().lower().decode()] = v.strip().decode()
    return status, headers, body


@pytest.fixture(scope="module")
def daemon(paths, tmp_path_factory):
    """One ntscontactd for a test module (default flags, 127.0.0.1, free port)."""
    d = start_daemon(paths.bin / "ntscontactd", tmp_path_factory.mktemp("ntscontactd") / "daemon.log")
    yield d
    assert d.stop() == 0, d.log()[-2000:]


@pytest.fixture
def daemon_factory(paths, tmp_path):
    """start(*flags) -> Daemon with its own flags; every one is stopped at teardown."""
    started = []

    def start(*flags):
        d = start_daemon(paths.bin / "ntscontactd", tmp_path / f"daemon{len(started)}.log", *flags)
        started.append(d)
        return d

    yield start
    for d in started:
        d.stop()


# ------------------------------------------------------------ scene helpers
# Positions in global order (bodies in scene order, nodes in body order), and a
# scene document moved to new positions: what every session test compares.
import copy  # noqa: E402

import numpy as np  # noqa: E402


def positions_of(scene):
    """(N, 2) float64: every node of a scene document, in global order."""
    return np.concatenate([np.asarray(b["nodes"], dtype=float).reshape(-1, 2) for b in scene["bodies"]])


def with_positions(scene, pos):
    """A copy of a scene document with its nodes at `pos` (global order)."""
    out = copy.deepcopy(scene)
    k = 0
    for b in out["bodies"]:
        n = len(b["nodes"])
        b["nodes"] = np.asarray(pos[k:k + n]).tolist()
        k += n
    return out


@pytest.fixture(scope="module")
def tls_pair(tmp_path_factory):
    """A self-signed certificate and key for 127.0.0.1 (PEM paths), made once
    per test module; skipped without openssl."""
    if shutil.which("openssl") is None:
        pytest.skip("needs openssl to make a certificate")
    d = tmp_path_factory.mktemp("tls")
    key, cert = d / "key.pem", d / "cert.pem"
    subprocess.run(["openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-keyout", str(key), "-out",
                    str(cert), "-days", "1", "-subj", "/CN=127.0.0.1", "-addext", "subjectAltName=IP:127.0.0.1"],
                   check=True, capture_output=True, timeout=60)
    return cert, key


import contextlib  # noqa: E402


@contextlib.contextmanager
def full_disk(where, size="8k"):
    """A directory on a file system of `size` bytes (a tmpfs at `where`, made
    and removed here), to fill up; the test is skipped where one cannot be
    mounted (not root, a container without the right)."""
    where.mkdir()
    mounted = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(where)],
                             capture_output=True)
    if mounted.returncode != 0:
        pytest.skip("cannot mount a small tmpfs here: " + mounted.stderr.decode().strip())
    try:
        yield where
    finally:
        subprocess.run(["umount", str(where)], capture_output=True)

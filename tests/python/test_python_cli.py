"""`python -m ntscontact`'s commands against a daemon with a token and TLS:
--token, --token-file and --ca reach it, a TLS failure says so (not
"cannot connect"), and `contact --engine` / `engine` work with no daemon."""
import json
import os
import subprocess
import sys

import pytest

from conftest import start_daemon

ntscontact = pytest.importorskip("ntscontact")
from test_access import SCENE  # noqa: E402


def py(*args, env=None, stdin=None):
    e = dict(os.environ)
    e.pop("NTSCONTACT_TOKEN", None)
    e.update(env or {})
    return subprocess.run([sys.executable, "-m", "ntscontact", *map(str, args)], capture_output=True, text=True,
                          env=e, input=stdin, timeout=120)


@pytest.fixture(scope="module")
def secured(paths, tls_pair, tmp_path_factory):
    """A daemon with a token file and TLS: (https base URL, certificate, token file)."""
    tmp = tmp_path_factory.mktemp("secured")
    cert, key = tls_pair
    tokens = tmp / "tokens"
    tokens.write_text("cli-token-7\n")
    d = start_daemon(paths.bin / "ntscontactd", tmp / "d.log", "--token-file", tokens, "--tls-cert", cert,
                     "--tls-key", key)
    yield d.base.replace("http://", "https://"), cert, tokens
    assert d.stop() == 0


def test_token_and_ca_reach_the_daemon(secured, tmp_path):
    base, cert, tokens = secured
    scene = tmp_path / "scene.json"
    scene.write_text(json.dumps(SCENE))
    r = py("health", "--url", base, "--ca", cert, "--token", "cli-token-7")
    assert r.returncode == 0, r.stderr
    assert "build" in json.loads(r.stdout)  # the details: the token was sent
    r = py("contact", scene, "--url", base, "--ca", cert, "--token-file", tokens)
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["summary"]["contacts"] > 0
    r = py("contact", scene, "--url", base, "--ca", cert, env={"NTSCONTACT_TOKEN": "cli-token-7"})
    assert r.returncode == 0, r.stderr
    r = py("contact", scene, "--url", base, "--ca", cert, "--token", "wrong")
    assert r.returncode == 1 and "unauthorized" in r.stderr and "401" in r.stderr


def test_a_tls_failure_says_so(secured, tmp_path):
    base, cert, tokens = secured
    r = py("health", "--url", base, "--token-file", tokens)  # the self-signed certificate is not trusted
    assert r.returncode == 1
    assert "tls_failed" in r.stderr and "TLS failed" in r.stderr and "--ca" in r.stderr
    assert "cannot connect" not in r.stderr
    with ntscontact.Client(base, timeout=10) as c:
        with pytest.raises(ntscontact.TLSError):
            c.health()


def test_contact_in_process_equals_the_daemons(daemon, paths):
    scene = paths.examples / "two_disks.json"
    here = py("contact", scene, "--engine", "--outputs", "forces,contacts")
    there = py("contact", scene, "--url", daemon.base, "--outputs", "forces,contacts")
    assert here.returncode == 0 and there.returncode == 0, here.stderr + there.stderr
    a, b = json.loads(here.stdout), json.loads(there.stdout)
    a["summary"].pop("elapsed_ms"), b["summary"].pop("elapsed_ms")
    assert a == b and a["summary"]["contacts"] > 0


def test_engine_command_says_where_or_why(tmp_path):
    r = py("engine")
    assert r.returncode == 0 and r.stdout.startswith("engine: ") and "libntscontact_engine.so" in r.stdout
    r = py("engine", env={"NTSCONTACT_LIBRARY": str(tmp_path / "none.so")})
    assert r.returncode == 1 and "engine: none" in r.stdout


def test_usage_errors_exit_2(tmp_path, paths):
    scene = paths.examples / "two_disks.json"
    empty = tmp_path / "empty.tok"
    empty.write_text("# only a comment\n\n")
    binary = tmp_path / "bin.tok"
    binary.write_bytes(b"\xff\xfe\x00secret")
    for args in ([scene, "--token-file", empty], [scene, "--token-file", binary],
                 [scene, "--token", "a", "--token-file", empty], [scene, "--engine", "--threads", "-1"],
                 [scene, "--threads", "2"], [tmp_path / "nowhere.json"],
                 [scene, "--url", "https://127.0.0.1:9", "--ca", tmp_path / "nowhere.pem"]):
        r = py("contact", *args)
        assert r.returncode == 2, (args, r.stdout, r.stderr)
        assert "Traceback" not in r.stderr


def test_the_daemons_token_file_works_for_the_client(secured, tmp_path):
    base, cert, _ = secured
    tokens = tmp_path / "tokens"
    tokens.write_text("# the client's copy of a daemon token file\n\n  cli-token-7  \nanother\n")
    r = py("health", "--url", base, "--ca", cert, "--token-file", tokens)
    assert r.returncode == 0, r.stderr
    assert "build" in json.loads(r.stdout)


def test_a_reader_that_leaves_early_is_no_error(paths):
    """`python -m ntscontact contact ... | head`: the reader closes the pipe
    after a few bytes; the command stops quietly (141, as a C tool killed by
    SIGPIPE), without "Broken pipe" on stderr (it printed one and exited 1)."""
    env = dict(os.environ, NTS_BUILD_DIR=str(paths.build))
    proc = subprocess.Popen([sys.executable, "-m", "ntscontact", "contact", "--engine",
                             str(paths.examples / "jittered_packing.json")],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env)
    assert proc.stdout.read(10) == b'{"version"'
    proc.stdout.close()
    err = proc.stderr.read()
    assert proc.wait(timeout=120) == 141 and err == b"", err

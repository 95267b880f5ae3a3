"""valgrind memcheck of the CLI on every example scene (issue 7): zero errors,
zero definite or indirect leaks, in each mode (evaluate with every output and
pretty printing, validate) and on a few malformed inputs, whose error paths
must free everything too.

Skips, saying why, when valgrind is not installed or when the binaries were
built with the sanitizers (valgrind cannot run ASan binaries; the sanitized
run of the suite covers memory errors there)."""
import os
import pathlib
import shutil
import subprocess

import pytest

VALGRIND = shutil.which("valgrind")


def _sanitized(build):
    cache = pathlib.Path(build) / "CMakeCache.txt"
    if os.environ.get("NTS_SANITIZED") == "1":
        return True
    return cache.exists() and "NTS_SANITIZE:BOOL=ON" in cache.read_text(errors="replace")


pytestmark = [
    pytest.mark.skipif(VALGRIND is None, reason="valgrind is not installed (Debian package: valgrind)"),
]

EXAMPLES = sorted((pathlib.Path(__file__).resolve().parents[2] / "examples").glob("*.json"))

MALFORMED = {
    "broken_json": b'{"version": 1, "bodies": [',
    "duplicate_id": (b'{"version":1,"options":{"penalty":1},"bodies":['
                     b'{"id":"a","nodes":[[0,0],[1,0],[0,1]]},{"id":"a","nodes":[[5,0],[6,0],[5,1]]}]}'),
    "degenerate_segment": (b'{"version":1,"options":{"penalty":1},"bodies":['
                           b'{"id":"a","nodes":[[0,0],[1,0],[1,0],[0,1]]}]}'),
    "non_manifold_mesh": (b'{"version":1,"options":{"penalty":1},"bodies":[{"id":"m","nodes":'
                          b'[[0,0],[1,0],[0,1],[1,1],[-1,-1]],"triangles":[[0,1,2],[1,3,2],[1,2,4],[0,1,4]]}]}'),
}


def _memcheck(paths, tmp_path, args, stdin=None):
    if _sanitized(paths.build):
        pytest.skip("binaries built with -DNTS_SANITIZE=ON: valgrind runs on the plain build")
    if not paths.cli.exists():
        pytest.fail(f"{paths.cli} is not built")
    log = tmp_path / "valgrind.log"
    cmd = [VALGRIND, "--tool=memcheck", "--error-exitcode=99", "--leak-check=full",
           "--errors-for-leak-kinds=definite,indirect", "--show-leak-kinds=definite,indirect",
           "--track-origins=yes", f"--log-file={log}", str(paths.cli), *args]
    proc = subprocess.run(cmd, input=stdin, stdout=subprocess.PIPE, stderr=subprocess.PIPE, timeout=600)
    text = log.read_text(errors="replace")
    assert proc.returncode != 99, f"valgrind found errors or leaks:\n{text[-6000:]}"
    assert "ERROR SUMMARY: 0 errors" in text, text[-6000:]
    # OpenMP's thread pool may stay reachable at exit; nothing may be lost.
    assert "definitely lost: 0 bytes" in text or "All heap blocks were freed" in text, text[-4000:]
    assert "indirectly lost: 0 bytes" in text or "All heap blocks were freed" in text, text[-4000:]
    return proc


def test_examples_exist():
    assert EXAMPLES, "no example scenes in examples/"


@pytest.mark.parametrize("scene", EXAMPLES, ids=[p.stem for p in EXAMPLES])
def test_cli_evaluate_clean(paths, tmp_path, scene):
    proc = _memcheck(paths, tmp_path, ["--pretty", "--outputs", "forces,energy,virial,contacts,gaps",
                                       "-o", str(tmp_path / "out.json"), str(scene)])
    assert proc.returncode == 0, proc.stderr.decode(errors="replace")
    assert (tmp_path / "out.json").read_text().lstrip().startswith("{")


@pytest.mark.parametrize("scene", EXAMPLES, ids=[p.stem for p in EXAMPLES])
def test_cli_validate_clean(paths, tmp_path, scene):
    proc = _memcheck(paths, tmp_path, ["--validate", "-"], stdin=scene.read_bytes())
    assert proc.returncode == 0, proc.stderr.decode(errors="replace")


@pytest.mark.parametrize("name", sorted(MALFORMED))
def test_cli_error_paths_clean(paths, tmp_path, name):
    proc = _memcheck(paths, tmp_path, ["-"], stdin=MALFORMED[name])
    assert proc.returncode == 3, proc.stderr.decode(errors="replace")


def test_daemon_clean(paths, tmp_path):
    """The daemon under memcheck: every example posted to /v1/contact and
    /v1/validate, a malformed request, a 404, a 405, a health check; then
    SIGTERM: exit 0, zero errors, nothing definitely or indirectly lost."""
    import json
    import selectors
    import signal
    import urllib.error
    import urllib.request

    if _sanitized(paths.build):
        pytest.skip("binaries built with -DNTS_SANITIZE=ON: valgrind runs on the plain build")
    binary = paths.bin / "ntscontactd"
    if not binary.exists():
        pytest.fail(f"{binary} is not built")
    log = tmp_path / "valgrind.log"
    cmd = [VALGRIND, "--tool=memcheck", "--error-exitcode=99", "--leak-check=full",
           "--errors-for-leak-kinds=definite,indirect", "--show-leak-kinds=definite,indirect",
           f"--log-file={log}", str(binary), "--host", "127.0.0.1", "--port", "0", "--quiet", "--threads", "2"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, stdin=subprocess.DEVNULL)
    try:
        sel = selectors.DefaultSelector()
        sel.register(proc.stdout, selectors.EVENT_READ)
        line = proc.stdout.readline().decode() if sel.select(120) else ""
        sel.close()
        assert line.startswith("ntscontactd listening on "), line
        base = "http://127.0.0.1:" + line.strip().rsplit(":", 1)[1]

        def call(method, path, body=None):
            req = urllib.request.Request(base + path, data=body, method=method,
                                         headers={"Content-Type": "application/json"})
            try:
                with urllib.request.urlopen(req, timeout=300) as r:
                    return r.status, r.read()
            except urllib.error.HTTPError as e:
                return e.code, e.read()

        for scene in EXAMPLES:
            assert call("POST", "/v1/contact", scene.read_bytes())[0] == 200
            assert call("POST", "/v1/validate", scene.read_bytes())[0] == 200
        for body in MALFORMED.values():
            assert call("POST", "/v1/contact", body)[0] == 400
        assert call("GET", "/v1/nothing")[0] == 404
        assert call("GET", "/v1/contact")[0] == 405
        status, doc = call("GET", "/v1/health")
        assert status == 200 and json.loads(doc)["status"] == "ok"
    finally:
        if proc.poll() is None:
            proc.send_signal(signal.SIGTERM)
        try:
            rc = proc.wait(timeout=300)
        except subprocess.TimeoutExpired:
            proc.kill()
            rc = proc.wait()
        proc.stdout.close()
    text = log.read_text(errors="replace")
    assert rc != 99, f"valgrind found errors or leaks:\n{text[-6000:]}"
    assert rc == 0, text[-4000:]
    assert "ERROR SUMMARY: 0 errors" in text, text[-6000:]

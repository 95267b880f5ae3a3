"""Bounds that hold for any input that fits the byte limit (issue 13 item 3):
2,000 identical triangles piled on one spot (79 KB of JSON) used to cost 2.4
GB and 8-15 s; now the candidate budget answers with a clear error, in the
CLI and the daemon, and --max-seconds stops the evaluation itself."""
import json
import os
import pathlib
import subprocess

import requests

REPO = pathlib.Path(__file__).resolve().parents[2]
CLI = pathlib.Path(os.environ.get("NTS_BUILD_DIR", str(REPO / "build"))) / "bin" / "ntscontact"


def pile(n):
    return {"options": {"penalty": 1.0}, "bodies": [{"id": i, "nodes": [[0, 0], [1, 0], [0, 1]]} for i in range(n)]}


def test_a_pile_of_triangles_is_a_clear_error():
    body = json.dumps(pile(2000)).encode()
    assert len(body) < 100_000
    r = subprocess.run([str(CLI), "-"], input=body, capture_output=True, timeout=120)
    assert r.returncode == 3
    assert r.stderr.decode().startswith('ntscontact: limit_exceeded at "": more than max_candidates = ')
    # A smaller budget, given: the same error, sooner.
    r = subprocess.run([str(CLI), "--max-candidates", "1000", "-"], input=json.dumps(pile(50)).encode(),
                       capture_output=True, timeout=60)
    assert r.returncode == 3 and b"max_candidates = 1000" in r.stderr
    r = subprocess.run([str(CLI), "--max-candidates", "1M", "--outputs", "gaps", "-"],
                       input=json.dumps(pile(50)).encode(), capture_output=True, timeout=60)
    assert r.returncode == 0 and len(json.loads(r.stdout)["gaps"]) == 150 * 49


def test_the_daemon_answers_the_pile_with_400(daemon_factory):
    d = daemon_factory("--max-candidates", "10000")
    r = requests.post(d.url("/v1/contact"), data=json.dumps(pile(100)), headers={"Content-Type": "application/json"},
                      timeout=60)
    assert r.status_code == 400 and r.json()["error"]["code"] == "limit_exceeded"
    assert "max_candidates" in r.json()["error"]["message"]
    assert requests.get(d.url("/v1/health"), timeout=10).status_code == 200


def test_max_seconds_stops_the_evaluation():
    """A brute-force search of 40,000 nodes takes seconds; --max-seconds 0.2
    stops it inside the core: the answer is limit_exceeded, well before the
    evaluation would have ended (the bound is checked every 1024 slaves)."""
    bodies = []
    for k in range(100):
        t = [[2.0 * (k % 10) + 1.0 + 0.99 * __import__("math").cos(6.283185307 * j / 400),
              2.0 * (k // 10) + 1.0 + 0.99 * __import__("math").sin(6.283185307 * j / 400)] for j in range(400)]
        bodies.append({"id": k, "nodes": t})
    doc = {"options": {"penalty": 1.0, "search": "brute_force"}, "bodies": bodies}
    r = subprocess.run([str(CLI), "--max-seconds", "0.2", "-"], input=json.dumps(doc).encode(), capture_output=True,
                       timeout=120)
    assert r.returncode == 3, r.stdout[:200]
    assert r.stderr.decode().startswith('ntscontact: limit_exceeded at "": the request took ')
    assert "max_seconds = 0.2" in r.stderr.decode()

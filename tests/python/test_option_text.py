"""One text, one value, at every door: an option's number written as text
(the CLI's flags, a session step's query parameters) is read as the same
number in a request's JSON is read (RFC 8259's grammar, the nearest double:
ntsj_parse_double), and a list of outputs or a query parameter given twice is
refused at every door, as JSON refuses a key twice. A campaign across the
doors found the query taking hex, a '+', a space and an option twice (the
last one winning), and the CLI taking "forces,forces" and refusing 1e-400,
which JSON reads as 0."""
import json
import subprocess

import pytest
import requests

from conftest import REPO, start_daemon

SCENE = REPO / "examples" / "two_disks.json"
JSON = {"Content-Type": "application/json"}
TEXTS = ["0.25", "2.5e-1", "25E-2", "-0", "0", "1e-400", "0.30000000000000004", "+0.25", "0x1p-2", " 0.25",
         "0.25 ", ".25", "0.", "025", "1e999", "-1e999", "NaN", "inf", "", "0.25x", "1e", "--1"]


@pytest.fixture(scope="module")
def daemon(paths, tmp_path_factory):
    d = start_daemon(paths.bin / "ntscontactd", tmp_path_factory.mktemp("option_text") / "daemon.log")
    yield d
    assert d.stop() == 0, d.log()[-2000:]


def cli(paths, *flags):
    r = subprocess.run([str(paths.cli), *flags, str(SCENE)], capture_output=True, timeout=60)
    return r.returncode, (json.loads(r.stdout) if r.returncode == 0 else r.stderr.decode())


def by_cli(paths, text):
    rc, out = cli(paths, "--search-radius", text)
    assert rc in (0, 2), (text, rc, out)
    return out["summary"]["search_radius"].hex() if rc == 0 else None


def by_json(paths, text):
    """The text as the option's JSON value, in the scene's own text."""
    doc = SCENE.read_text().replace('"search_radius":0.1', '"search_radius":%s' % text, 1)
    assert doc != SCENE.read_text()
    r = subprocess.run([str(paths.cli), "-"], input=doc.encode(), capture_output=True, timeout=60)
    assert r.returncode in (0, 3), (text, r.returncode, r.stderr)
    return json.loads(r.stdout)["summary"]["search_radius"].hex() if r.returncode == 0 else None


def by_query(daemon, sid, text):
    r = requests.post(daemon.url(f"/v1/scenes/{sid}/contact"), data=b"", params={"search_radius": text},
                      headers={"Content-Type": "application/octet-stream"}, timeout=60)
    assert r.status_code in (200, 400), (text, r.status_code, r.text)
    return r.json()["summary"]["search_radius"].hex() if r.status_code == 200 else None


def test_a_number_is_read_alike_at_every_door(paths, daemon):
    sid = requests.post(daemon.url("/v1/scenes"), data=SCENE.read_bytes(), headers=JSON, timeout=60).json()["id"]
    taken = 0
    for text in TEXTS:
        want = by_json(paths, text) if text.strip() == text and text else None  # (JSON's own spaces aside)
        assert by_cli(paths, text) == want, text
        assert by_query(daemon, sid, text) == want, text
        taken += want is not None
    assert taken == 7  # the first seven: 0.25 three ways, -0, 0, 1e-400 (0) and 0.30000000000000004


def test_outputs_twice_or_a_trailing_comma_are_refused_at_every_door(paths, daemon):
    sid = requests.post(daemon.url("/v1/scenes"), data=SCENE.read_bytes(), headers=JSON, timeout=60).json()["id"]
    for text in ("forces,forces", "forces,"):
        rc, err = cli(paths, "--outputs", text)
        assert rc == 2 and "--outputs" in err, (text, rc, err)
        r = requests.post(daemon.url(f"/v1/scenes/{sid}/contact"), data=b"", params={"outputs": text},
                          headers={"Content-Type": "application/octet-stream"}, timeout=60)
        assert r.status_code == 400 and r.json()["error"]["code"] == "invalid_value", (text, r.text)
    doc = json.loads(SCENE.read_text())
    doc["options"]["outputs"] = ["forces", "forces"]
    r = subprocess.run([str(paths.cli), "-"], input=json.dumps(doc).encode(), capture_output=True, timeout=60)
    assert r.returncode == 3, r.stderr


@pytest.mark.parametrize("query, pointer", [
    ("penalty=100&penalty=200", "/options/penalty"),
    ("outputs=forces&outputs=energy", "/options/outputs"),
    ("commit=true&commit=true", "/commit"),
    ("nodes=all&nodes=all", "/nodes"),
])
def test_a_query_parameter_twice_is_refused(daemon, query, pointer):
    """invalid_value, as nodes and commit twice always were (docs/sessions.md);
    an option given twice was taken, the last one winning."""
    sid = requests.post(daemon.url("/v1/scenes"), data=SCENE.read_bytes(), headers=JSON, timeout=60).json()["id"]
    r = requests.post(daemon.url(f"/v1/scenes/{sid}/contact?{query}"), data=b"",
                      headers={"Content-Type": "application/octet-stream", "Accept": "application/octet-stream"},
                      timeout=60)
    assert r.status_code == 400, r.text
    err = r.json()["error"]
    assert err["code"] == "invalid_value" and err["pointer"] == pointer and "given twice" in err["message"], err

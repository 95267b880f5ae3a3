"""Contact state that persists (issue 24 §4): a session created with
"session": {"keep_contacts": true} keeps each step's contacts and matches the
next step's to them by key (slave node, master body, master feature); the
stateless route and the CLI refuse to keep anything; a session that does not
ask answers as before. The matches are checked against a matcher written here
from the contacts of two steps."""
import json
import subprocess

import jsonschema
import numpy as np
import pytest
import requests

from conftest import positions_of, start_daemon

OUTPUTS = {"outputs": ["forces", "energy", "virial", "contacts"]}


@pytest.fixture(scope="module")
def daemon(paths, tmp_path_factory):
    d = start_daemon(paths.bin / "ntscontactd", tmp_path_factory.mktemp("memory") / "daemon.log", "--threads", "2")
    yield d
    assert d.stop() == 0, d.log()[-2000:]


def scene(paths, keep=True):
    doc = json.loads((paths.examples / "jittered_packing.json").read_text())
    if keep is not None:
        doc["session"] = {"keep_contacts": keep}
    return doc


def key(c):
    m = c["master"]
    feature = m["nodes"][1] if m["kind"] == "corner" else m["nodes"][0]
    return (c["slave"]["body"], c["slave"]["node"], m["body"]), (m["kind"], feature)


def expected(prev, now):
    """previous index and persisted flag of each contact of `now`, and the counts."""
    by_pair = {}
    for i, c in enumerate(prev):
        pair, _ = key(c)
        assert pair not in by_pair  # one contact per (slave node, master body)
        by_pair[pair] = i
    out, used = [], set()
    for c in now:
        pair, feat = key(c)
        i = by_pair.get(pair, -1)
        out.append((i, i >= 0 and key(prev[i])[1] == feat))
        if i >= 0:
            used.add(i)
    changes = {"persisted": sum(1 for i, p in out if p), "moved": sum(1 for i, p in out if i >= 0 and not p),
               "added": sum(1 for i, _ in out if i < 0), "ended": len(prev) - len(used)}
    return out, changes


def step(daemon, sid, pos, result_validator):
    r = requests.post(daemon.url(f"/v1/scenes/{sid}/contact"), json={"positions": pos.tolist(), "options": OUTPUTS},
                      timeout=60)
    assert r.status_code == 200, r.text
    doc = r.json()
    result_validator.validate(doc)
    return doc


def test_steps_match_by_key(daemon, paths, schemas):
    v = jsonschema.Draft202012Validator(schemas["result"])
    doc = scene(paths)
    r = requests.post(daemon.url("/v1/scenes"), json=doc, timeout=60)
    assert r.status_code == 201, r.text
    sid = r.json()["id"]
    pos = positions_of(doc)
    rng = np.random.default_rng(7)
    prev = []
    seen = {"persisted": 0, "moved": 0, "added": 0, "ended": 0}
    for k in range(8):
        res = step(daemon, sid, pos, v)
        contacts = res["contacts"]
        want, changes = expected(prev, contacts)
        assert [(c["previous"], c["persisted"]) for c in contacts] == want
        assert res["summary"]["contact_changes"] == changes
        if k == 0:
            assert changes["added"] == len(contacts) > 10
        for name in seen:
            seen[name] += changes[name] if k > 0 else 0
        prev = contacts
        pos = pos + rng.uniform(-0.004, 0.004, pos.shape)
    assert all(seen[n] > 0 for n in ("persisted", "moved")), seen
    # The same positions again: every contact persisted, at its own index.
    res = step(daemon, sid, pos - 0.0, v)
    res2 = step(daemon, sid, pos - 0.0, v)
    assert res2["summary"]["contact_changes"] == {"persisted": len(res["contacts"]), "moved": 0, "added": 0,
                                                  "ended": 0}
    assert [c["previous"] for c in res2["contacts"]] == list(range(len(res2["contacts"])))
    # A binary step counts too: the JSON step after it is matched to its contacts.
    data = np.ascontiguousarray(pos + 10.0 * np.arange(len(pos))[:, None], dtype="<f8").tobytes()
    rb = requests.post(daemon.url(f"/v1/scenes/{sid}/contact"), data=data,
                       headers={"Content-Type": "application/octet-stream", "Accept": "application/octet-stream"},
                       timeout=60)
    assert rb.status_code == 200, rb.text
    assert int(rb.headers["NTS-Contacts"]) == 0  # every node far apart
    res3 = step(daemon, sid, pos, v)
    assert res3["summary"]["contact_changes"]["added"] == len(res3["contacts"]) > 0
    assert res3["summary"]["contact_changes"]["ended"] == 0


def test_a_session_that_keeps_nothing_answers_as_before(daemon, paths):
    for keep in (None, False):
        doc = scene(paths, keep)
        r = requests.post(daemon.url("/v1/scenes"), json=doc, timeout=60)
        assert r.status_code == 201, r.text
        res = requests.post(daemon.url(f"/v1/scenes/{r.json()['id']}/contact"),
                            json={"positions": positions_of(doc).tolist(), "options": OUTPUTS}, timeout=60).json()
        assert "contact_changes" not in res["summary"]
        assert all("previous" not in c and "persisted" not in c for c in res["contacts"])
        plain = scene(paths, None)
        plain["options"].update(OUTPUTS)
        full = requests.post(daemon.url("/v1/contact"), json=plain, timeout=60).json()
        res["summary"].pop("elapsed_ms")
        full["summary"].pop("elapsed_ms")
        assert res == full


@pytest.mark.parametrize("session,pointer,code", [
    ({"keep_contacts": 1}, "/session/keep_contacts", "invalid_type"),
    ({"keep": True}, "/session/keep", "unknown_field"),
    ([True], "/session", "invalid_type"),
])
def test_bad_session_field(daemon, paths, session, pointer, code):
    doc = scene(paths, None)
    doc["session"] = session
    r = requests.post(daemon.url("/v1/scenes"), json=doc, timeout=60)
    assert r.status_code == 400, r.text
    assert r.json()["error"]["code"] == code and r.json()["error"]["pointer"] == pointer


def test_the_stateless_route_keeps_nothing(daemon, paths):
    r = requests.post(daemon.url("/v1/contact"), json=scene(paths), timeout=60)
    assert r.status_code == 400, r.text
    assert r.json()["error"]["pointer"] == "/session"
    assert "session" in r.json()["error"]["message"]
    # A scene meant for a session still validates.
    assert requests.post(daemon.url("/v1/validate"), json=scene(paths), timeout=60).status_code == 200


def test_the_cli_keeps_nothing(paths, tmp_path):
    f = tmp_path / "s.json"
    f.write_text(json.dumps(scene(paths)))
    proc = subprocess.run([str(paths.bin / "ntscontact"), str(f)], capture_output=True, timeout=60)
    assert proc.returncode != 0
    assert b"/session" in proc.stderr


def test_python_client_keeps_contacts(daemon, paths):
    import ntscontact
    doc = scene(paths, None)
    client = ntscontact.Client(daemon.url(""))
    with client.session(doc, keep_contacts=True) as s:
        first = s.contact(outputs=["forces", "contacts"])
        again = s.contact(outputs=["forces", "contacts"])
    assert all(c.previous == -1 and c.persisted is False for c in first.contacts)
    assert [c.previous for c in again.contacts] == list(range(len(again.contacts)))
    assert all(c.persisted for c in again.contacts)
    assert again.summary.extra["contact_changes"]["persisted"] == len(again.contacts) > 0
    with client.session(doc) as s:
        plain = s.contact(outputs=["forces", "contacts"])
    assert all(c.previous is None and c.persisted is None for c in plain.contacts)


def test_a_refused_step_is_not_the_previous_one(paths, tmp_path):
    """A step whose answer is refused after its evaluation (over --max-memory)
    does not become the step the next one is matched against."""
    import math
    k, m = 8, 16
    bodies = [{"id": f"b{i}_{j}", "nodes": [[i + 0.45 * math.cos(2 * math.pi * t / m),
                                             j + 0.45 * math.sin(2 * math.pi * t / m)] for t in range(m)]}
              for i in range(k) for j in range(k)]
    doc = {"version": 1, "options": {"penalty": 10.0, "outputs": ["forces", "contacts"]}, "bodies": bodies,
           "session": {"keep_contacts": True}}
    apart = positions_of(doc)
    # the centres 0.85 apart, the radii 0.45: neighbours overlap
    shift = np.repeat([[-0.15 * i, -0.15 * j] for i in range(k) for j in range(k)], m, axis=0)
    pressed = apart + shift
    d = start_daemon(paths.bin / "ntscontactd", tmp_path / "d.log", "--max-memory", "2M")
    try:
        r = requests.post(d.url("/v1/scenes"), json=doc, timeout=60)
        assert r.status_code == 201, r.text
        url = d.url(f"/v1/scenes/{r.json()['id']}/contact")
        a = requests.post(url, json={"positions": pressed.tolist()}, timeout=60)
        assert a.status_code == 200, a.text
        n = len(a.json()["contacts"])
        assert n > 50 and a.json()["summary"]["contact_changes"]["added"] == n
        # Apart (no contact), and an answer of every gap: refused after the evaluation.
        b = requests.post(url + "?outputs=forces,gaps,contacts&search_radius=16", json={"positions": apart.tolist()},
                          timeout=120)
        assert b.status_code == 413, b.status_code
        c = requests.post(url, json={"positions": pressed.tolist()}, timeout=60)
        assert c.status_code == 200, c.text
        # Matched against the answered step a, not the refused b (which had none).
        assert c.json()["summary"]["contact_changes"] == {"persisted": n, "moved": 0, "added": 0, "ended": 0}
    finally:
        assert d.stop() == 0


def test_the_cli_frames_keep_contacts_when_asked(paths, tmp_path):
    doc = json.loads((paths.examples / "two_disks.json").read_text())
    doc["session"] = {"keep_contacts": True}
    (tmp_path / "s.json").write_text(json.dumps(doc))
    pos = positions_of(doc)
    (tmp_path / "f.bin").write_bytes(np.concatenate([pos, pos]).astype("<f8").tobytes())
    proc = subprocess.run([str(paths.bin / "ntscontact"), "--frames", str(tmp_path / "f.bin"), "--outputs",
                           "forces,contacts", str(tmp_path / "s.json")], capture_output=True, timeout=60)
    assert proc.returncode == 0, proc.stderr.decode()
    first, second = [json.loads(line) for line in proc.stdout.decode().splitlines()]
    n = len(first["contacts"])
    assert n > 0 and first["summary"]["contact_changes"]["added"] == n
    assert second["summary"]["contact_changes"] == {"persisted": n, "moved": 0, "added": 0, "ended": 0}
    assert [c["previous"] for c in second["contacts"]] == list(range(n))

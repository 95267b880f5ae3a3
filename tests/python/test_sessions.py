"""Scene sessions over HTTP (POST /v1/scenes, /v1/scenes/{id}/contact, GET and
DELETE /v1/scenes/{id}): a step's answer equals, bit for bit, POST /v1/contact
on the full scene at the same positions and options (summary.elapsed_ms aside),
in JSON and in binary; bad input gets a 4xx naming its place; the store keeps
to its bounds."""
import copy
import json
import threading
import time

import jsonschema
import numpy as np
import pytest
import requests

from conftest import positions_of, start_daemon, with_positions

EXAMPLES = ["two_disks", "jittered_packing", "periodic_packing", "triangle_meshes"]
OCTET = {"Content-Type": "application/octet-stream"}
BINARY = {"Content-Type": "application/octet-stream", "Accept": "application/octet-stream"}


@pytest.fixture(scope="module")
def daemon(paths, tmp_path_factory):
    d = start_daemon(paths.bin / "ntscontactd", tmp_path_factory.mktemp("sessions") / "daemon.log", "--threads", "2")
    yield d
    assert d.stop() == 0, d.log()[-2000:]


@pytest.fixture(scope="module")
def validators(schemas):
    session = schemas["session"]
    defs = lambda name: {**session["$defs"][name], "$defs": session["$defs"]}  # noqa: E731
    return {
        "created": jsonschema.Draft202012Validator(defs("created")),
        "info": jsonschema.Draft202012Validator(defs("info")),
        "step": jsonschema.Draft202012Validator(defs("step")),
        "result": jsonschema.Draft202012Validator(schemas["result"]),
        "error": jsonschema.Draft202012Validator(schemas["error"]),
    }


def load(paths, name):
    return json.loads((paths.examples / f"{name}.json").read_text())




def without_elapsed(doc):
    doc = copy.deepcopy(doc)
    doc["summary"].pop("elapsed_ms", None)
    return doc


def forces_of(result):
    return np.concatenate([np.asarray(b["forces"], dtype=float).reshape(-1, 2) for b in result["bodies"]])


def create(daemon, scene, validators):
    r = requests.post(daemon.url("/v1/scenes"), json=scene, timeout=60)
    assert r.status_code == 201, r.text
    doc = r.json()
    validators["created"].validate(doc)
    assert r.headers["Location"] == f"/v1/scenes/{doc['id']}"
    return doc


def full_contact(daemon, scene):
    r = requests.post(daemon.url("/v1/contact"), json=scene, timeout=60)
    assert r.status_code == 200, r.text
    return r.json()


def step_json(daemon, sid, body, **kw):
    return requests.post(daemon.url(f"/v1/scenes/{sid}/contact"), json=body, timeout=60, **kw)


def step_binary(daemon, sid, pos, params=None):
    data = np.ascontiguousarray(pos, dtype="<f8").tobytes()
    return requests.post(daemon.url(f"/v1/scenes/{sid}/contact"), data=data, headers=BINARY, params=params,
                         timeout=60)


def check_error(validators, r, status, code, pointer=None):
    assert r.status_code == status, (r.status_code, r.text)
    assert r.headers["Content-Type"].startswith("application/json")
    doc = r.json()
    validators["error"].validate(doc)
    assert doc["error"]["code"] == code, doc
    if pointer is not None:
        assert doc["error"]["pointer"] == pointer, doc
    return doc["error"]


def assert_binary_equals(r, result):
    """A binary answer carries the forces and the summary of `result`, bit for bit."""
    assert r.status_code == 200, r.text
    assert r.headers["Content-Type"] == "application/octet-stream"
    forces = np.frombuffer(r.content, dtype="<f8").reshape(-1, 2)
    assert np.array_equal(forces, forces_of(result))
    s = result["summary"]
    assert float(r.headers["NTS-Energy"]) == s["energy"]
    assert [float(v) for v in r.headers["NTS-Virial"].split(",")] == [s["virial"][k] for k in ("xx", "yy", "xy")]
    assert int(r.headers["NTS-Contacts"]) == s["contacts"]
    assert float(r.headers["NTS-Max-Penetration"]) == s["max_penetration"]
    assert float(r.headers["NTS-Elapsed-Ms"]) >= 0.0
    assert int(r.headers["NTS-Gaps"]) == s["gaps"]
    assert int(r.headers["NTS-Loops-Reversed"]) == s["loops_reversed"]
    assert float(r.headers["NTS-Search-Radius"]) == s["search_radius"]
    assert float(r.headers["NTS-Cell-Size"]) == s["cell_size"]


# ------------------------------------------------------------ bit for bit

@pytest.mark.parametrize("name", EXAMPLES)
def test_steps_equal_full_scene_calls(daemon, paths, validators, name):
    scene = load(paths, name)
    scene.setdefault("options", {})["outputs"] = ["forces", "energy", "virial", "contacts", "gaps"]
    doc = create(daemon, scene, validators)
    pos0 = positions_of(scene)
    assert doc["nodes"] == len(pos0) and doc["bodies"] == len(scene["bodies"])
    rng = np.random.default_rng(sum(map(ord, name)))
    scale = float(np.ptp(pos0[:, 0])) * 1e-3
    for step in range(4):
        # Rigid moves of whole bodies plus a jitter of every node.
        pos = pos0.copy()
        k = 0
        for b in scene["bodies"]:
            n = len(b["nodes"])
            pos[k:k + n] += rng.normal(scale=3 * scale, size=2) + rng.normal(scale=scale, size=(n, 2))
            k += n
        want = full_contact(daemon, with_positions(scene, pos))
        r = step_json(daemon, doc["id"], {"positions": pos.tolist()})
        assert r.status_code == 200, r.text
        got = r.json()
        validators["result"].validate(got)
        assert without_elapsed(got) == without_elapsed(want)
        assert_binary_equals(step_binary(daemon, doc["id"], pos), want)
    # An empty body: the stored positions (the last step's).
    r = requests.post(daemon.url(f"/v1/scenes/{doc['id']}/contact"), timeout=60)
    assert without_elapsed(r.json()) == without_elapsed(want)
    r = requests.post(daemon.url(f"/v1/scenes/{doc['id']}/contact"), data=b"", headers=BINARY, timeout=60)
    assert_binary_equals(r, want)
    info = requests.get(daemon.url(f"/v1/scenes/{doc['id']}"), timeout=10)
    assert info.status_code == 200
    validators["info"].validate(info.json())
    assert info.json()["steps"] == 10
    assert requests.delete(daemon.url(f"/v1/scenes/{doc['id']}"), timeout=10).status_code == 204


def test_step_options_equal_the_scene_options(daemon, paths, validators):
    scene = load(paths, "jittered_packing")
    doc = create(daemon, scene, validators)
    pos = positions_of(scene)
    over = {"penalty": 123.5, "alpha": 0.1, "solver": "newton", "search_radius": 0.05,
            "outputs": ["forces", "contacts"]}
    changed = copy.deepcopy(scene)
    changed["options"].update(over)
    want = full_contact(daemon, changed)
    r = step_json(daemon, doc["id"], {"positions": pos.tolist(), "options": over})
    assert without_elapsed(r.json()) == without_elapsed(want)
    assert "contacts" in r.json()
    # The same overrides as query parameters of a binary step.
    r = step_binary(daemon, doc["id"], pos, params={"penalty": "123.5", "alpha": "0.1", "solver": "newton",
                                                     "search_radius": "0.05", "outputs": "forces,contacts"})
    assert_binary_equals(r, want)
    # Overrides hold for one step only: the next one has the scene's options.
    r = step_json(daemon, doc["id"], {})
    assert without_elapsed(r.json()) == without_elapsed(full_contact(daemon, scene))
    # A JSON step may answer in binary too.
    r = step_json(daemon, doc["id"], {"positions": pos.tolist()}, headers={"Accept": "application/octet-stream"})
    assert_binary_equals(r, full_contact(daemon, scene))


def test_positions_that_change_the_scene_are_rebuilt(daemon, paths, validators):
    """Mirroring a body turns its loop over: the session builds the scene anew,
    as the full call does (loops_reversed counts the reversal)."""
    scene = load(paths, "two_disks")
    doc = create(daemon, scene, validators)
    pos = positions_of(scene)
    n0 = len(scene["bodies"][0]["nodes"])
    mirrored = pos.copy()
    cx = mirrored[n0:, 0].mean()
    mirrored[n0:, 0] = 2 * cx - mirrored[n0:, 0]
    want = full_contact(daemon, with_positions(scene, mirrored))
    assert want["summary"]["loops_reversed"] == 1
    got = step_json(daemon, doc["id"], {"positions": mirrored.tolist()}).json()
    assert without_elapsed(got) == without_elapsed(want)
    # And back.
    got = step_json(daemon, doc["id"], {"positions": pos.tolist()}).json()
    assert without_elapsed(got) == without_elapsed(full_contact(daemon, scene))


def polygon(n, r, centre, phase=0.0):
    t = phase + 2 * np.pi * np.arange(n) / n
    return np.c_[centre[0] + r * np.cos(t), centre[1] + r * np.sin(t)]


def test_length_scaling_does_not_depend_on_the_history(daemon, validators):
    """Issue 22 §4: with penalty per length, a step that builds the scene anew
    (a far body mirrored) used to measure every body's tributary lengths at
    that step's positions, so the same positions gave another answer after
    it. The session keeps its reference configuration (the positions it was
    created with) across rebuilds: the same positions give the same bits,
    and the full call gives them too with those positions as "reference"."""
    a, b, c = polygon(24, 1.0, (0, 0)), polygon(20, 1.0, (1.9, 0.05), 0.1), polygon(12, 0.5, (10, 0))
    scene = {"version": 1, "options": {"penalty": 100.0, "penalty_scaling": "length", "search_radius": 0.3,
                                       "outputs": ["forces", "energy", "virial", "contacts", "gaps"]},
             "bodies": [{"id": "a", "nodes": a.tolist()}, {"id": "b", "nodes": b.tolist()},
                        {"id": "c", "nodes": c.tolist()}]}
    doc = create(daemon, scene, validators)
    p = np.vstack([1.5 * a, b + [0.55, 0.0], c])  # a stretched: its segments are 1.5 times longer
    q = p.copy()
    q[44:, 0] = 20.0 - q[44:, 0]                  # c mirrored: a new scene
    first = step_json(daemon, doc["id"], {"positions": p.tolist()}).json()
    assert first["summary"]["contacts"] > 0 and first["summary"]["loops_reversed"] == 0
    mirrored = step_json(daemon, doc["id"], {"positions": q.tolist()}).json()
    assert mirrored["summary"]["loops_reversed"] == 1
    # c touches nothing: a and b see the same contacts, penalties and forces.
    assert mirrored["summary"]["energy"] == first["summary"]["energy"]
    assert mirrored["contacts"] == first["contacts"]
    assert mirrored["bodies"][:2] == first["bodies"][:2]
    again = step_json(daemon, doc["id"], {"positions": p.tolist()}).json()  # c turns back: a new scene again
    assert without_elapsed(again) == without_elapsed(first)
    assert_binary_equals(step_binary(daemon, doc["id"], q), mirrored)
    assert_binary_equals(step_binary(daemon, doc["id"], p), first)
    # The full call at p with the session's reference configuration: the same bits.
    full = with_positions(scene, p)
    for body, start in zip(full["bodies"], scene["bodies"]):
        body["reference"] = start["nodes"]
    assert without_elapsed(full_contact(daemon, full)) == without_elapsed(first)
    # Without it, the full call measures at p: a's share of the energy is 1.5 times larger.
    plain = full_contact(daemon, with_positions(scene, p))
    assert plain["summary"]["contacts"] == first["summary"]["contacts"]
    assert plain["summary"]["energy"] > 1.05 * first["summary"]["energy"]


def test_pressure_is_measured_at_the_reference_whatever_the_scaling(daemon, validators):
    """A slave's traction divides its force by its tributary length, measured
    in the reference configuration (docs/model.md (21)) with the default
    penalty_scaling ("node") too: a step's pressure is the full call's with
    the session's first positions as each body's reference, and another
    without it (the forces the same either way). docs/sessions.md said so
    only of "length" (a campaign across the doors found it)."""
    a, b = polygon(24, 1.0, (0, 0)), polygon(20, 1.0, (1.9, 0.05), 0.1)
    scene = {"version": 1, "options": {"penalty": 100.0, "search_radius": 0.3, "outputs": ["forces", "pressure"]},
             "bodies": [{"id": "a", "nodes": a.tolist()}, {"id": "b", "nodes": b.tolist()}]}
    doc = create(daemon, scene, validators)
    p = 1.1 * np.vstack([a, b])  # both 10% larger: every segment 1.1 times longer
    got = step_json(daemon, doc["id"], {"positions": p.tolist()}).json()
    full = with_positions(scene, p)
    for body, start in zip(full["bodies"], scene["bodies"]):
        body["reference"] = start["nodes"]
    assert without_elapsed(full_contact(daemon, full)) == without_elapsed(got)
    plain = full_contact(daemon, with_positions(scene, p))
    assert [x["forces"] for x in plain["bodies"]] == [x["forces"] for x in got["bodies"]]
    assert any(np.any(np.asarray(x["pressure"])) for x in got["bodies"])
    assert [x["pressure"] for x in plain["bodies"]] != [x["pressure"] for x in got["bodies"]]


def grid_mesh_and_disk():
    """A 5 x 5 grid mesh of the unit square and a disk pressed into its bottom edge."""
    nodes = [[0.25 * i, 0.25 * j] for j in range(5) for i in range(5)]
    tris = []
    for j in range(4):
        for i in range(4):
            v = 5 * j + i
            tris += [[v, v + 1, v + 6], [v, v + 6, v + 5]]
    return {"version": 1, "options": {"penalty": 100.0, "outputs": ["forces", "energy", "virial", "contacts", "gaps"]},
            "bodies": [{"id": "mesh", "nodes": nodes, "triangles": tris},
                       {"id": "disk", "nodes": polygon(24, 0.3, (0.55, -0.29), 0.1).tolist()}]}


def test_an_interior_triangle_turned_over_is_taken(daemon, validators):
    """Issue 22 §5: contact depends on a mesh's boundary. A FIRE iterate that
    turns one interior triangle over (node 12 pushed just past the edge 13-18
    of its neighbours) used to abort the run (the step rebuilt the scene and
    got non_manifold_mesh); it is taken, by the session and the full call, and
    gives the contacts of the mesh un-turned, whose boundary is the same."""
    scene = grid_mesh_and_disk()
    doc = create(daemon, scene, validators)
    pos = positions_of(scene)
    turned = pos.copy()
    turned[12] = [0.775, 0.625]
    tri = np.array(scene["bodies"][0]["triangles"])
    e1, e2 = turned[tri[:, 1]] - turned[tri[:, 0]], turned[tri[:, 2]] - turned[tri[:, 0]]
    assert np.flatnonzero(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0] < 0).tolist() == [20]
    before = step_json(daemon, doc["id"], {"positions": pos.tolist()}).json()
    assert before["summary"]["contacts"] > 0
    r = step_json(daemon, doc["id"], {"positions": turned.tolist()})
    assert r.status_code == 200, r.text
    validators["result"].validate(r.json())
    assert without_elapsed(r.json()) == without_elapsed(before)
    assert without_elapsed(full_contact(daemon, with_positions(scene, turned))) == without_elapsed(before)
    assert_binary_equals(step_binary(daemon, doc["id"], turned), before)
    # A session created at the turned positions too.
    doc = create(daemon, with_positions(scene, turned), validators)
    assert_binary_equals(step_binary(daemon, doc["id"], pos), before)


def test_a_failing_step_gives_the_full_calls_error_and_keeps_the_session(daemon, paths, validators):
    scene = load(paths, "two_disks")
    doc = create(daemon, scene, validators)
    pos = positions_of(scene)
    bad = pos.copy()
    bad[1] = bad[0]  # a zero-length segment
    full = requests.post(daemon.url("/v1/contact"), json=with_positions(scene, bad), timeout=60)
    r = step_json(daemon, doc["id"], {"positions": bad.tolist()})
    err = check_error(validators, r, 400, "degenerate_segment")
    assert r.json() == full.json()
    assert err["pointer"].startswith("/bodies/0")
    # The stored positions are still the good ones.
    r = requests.post(daemon.url(f"/v1/scenes/{doc['id']}/contact"), timeout=60)
    assert without_elapsed(r.json()) == without_elapsed(full_contact(daemon, scene))


# ------------------------------------------------------------ bad input

def test_bad_steps_are_4xx_naming_the_place(daemon, paths, validators):
    scene = load(paths, "two_disks")
    doc = create(daemon, scene, validators)
    sid, n = doc["id"], doc["nodes"]
    pos = positions_of(scene)
    url = daemon.url(f"/v1/scenes/{sid}/contact")

    r = requests.post(url, data=b"\0" * (16 * n - 8), headers=OCTET, timeout=10)
    e = check_error(validators, r, 400, "invalid_value", "")
    assert f"expected 16*N = 16 * {n} = {16 * n} bytes" in e["message"] and f"got {16 * n - 8}" in e["message"]
    bad = pos.copy()
    bad[57, 1] = np.nan
    e = check_error(validators, step_binary(daemon, sid, bad), 400, "non_finite", "/positions/57")
    assert "/bodies/1/nodes/" in e["message"]
    bad[57, 1] = np.inf
    check_error(validators, step_binary(daemon, sid, bad), 400, "non_finite", "/positions/57")
    check_error(validators, step_json(daemon, sid, {"positions": pos[:-1].tolist()}), 400, "invalid_value",
                "/positions")
    rows = pos.tolist()
    rows[3] = [1.0]
    check_error(validators, step_json(daemon, sid, {"positions": rows}), 400, "invalid_type", "/positions/3")
    rows[3] = [1.0, "x"]
    check_error(validators, step_json(daemon, sid, {"positions": rows}), 400, "invalid_type", "/positions/3")
    r = requests.post(url, data=b'{"positions": [[1e999, 0]]}', headers={"Content-Type": "application/json"},
                      timeout=10)
    check_error(validators, r, 400, "invalid_value", "/positions")  # the count is checked first
    check_error(validators, step_json(daemon, sid, {"options": {"friction": 1}}), 400, "unknown_field",
                "/options/friction")
    check_error(validators, step_json(daemon, sid, {"options": {"alpha": 0.9}}), 400, "invalid_option",
                "/options/alpha")
    check_error(validators, step_json(daemon, sid, {"options": {"search_radius": -1}}), 400, "invalid_option",
                "/options/search_radius")
    check_error(validators, step_json(daemon, sid, {"options": {"outputs": ["forces", "stress"]}}), 400,
                "invalid_value", "/options/outputs/1")
    check_error(validators, step_json(daemon, sid, {"positions": pos.tolist(), "extra": 1}), 400,
                "unknown_field", "/extra")
    check_error(validators, step_binary(daemon, sid, pos, params={"friction": "1"}), 400, "unknown_field",
                "/options/friction")
    check_error(validators, step_binary(daemon, sid, pos, params={"penalty": "abc"}), 400, "invalid_value",
                "/options/penalty")
    check_error(validators, step_binary(daemon, sid, pos, params={"penalty": "0"}), 400, "invalid_option",
                "/options/penalty")
    check_error(validators, step_binary(daemon, sid, pos, params={"outputs": "forces,bogus"}), 400,
                "invalid_value", "/options/outputs")
    r = requests.post(url, data=b"1,2", headers={"Content-Type": "text/csv"}, timeout=10)
    check_error(validators, r, 415, "unsupported_media_type")
    r = requests.post(url, data=b"{", headers={"Content-Type": "application/json"}, timeout=10)
    check_error(validators, r, 400, "invalid_json")
    # None of these changed the session: it still answers at its stored positions.
    r = requests.post(url, timeout=10)
    assert without_elapsed(r.json()) == without_elapsed(full_contact(daemon, scene))


def test_an_invalid_scene_makes_no_session(daemon, paths, validators):
    scene = load(paths, "two_disks")
    bad = copy.deepcopy(scene)
    bad["bodies"][1]["nodes"][2] = bad["bodies"][1]["nodes"][1]
    full = requests.post(daemon.url("/v1/contact"), json=bad, timeout=10)
    r = requests.post(daemon.url("/v1/scenes"), json=bad, timeout=10)
    check_error(validators, r, 400, "degenerate_segment")
    assert r.json() == full.json()
    r = requests.post(daemon.url("/v1/scenes"), data=b"[1,", headers={"Content-Type": "application/json"},
                      timeout=10)
    check_error(validators, r, 400, "invalid_json")
    box = copy.deepcopy(scene)
    box["options"]["periodic"] = {"lx": 0.3, "ly": 0.3}
    full = requests.post(daemon.url("/v1/contact"), json=box, timeout=10)
    r = requests.post(daemon.url("/v1/scenes"), json=box, timeout=10)
    check_error(validators, r, 400, "box_too_small")
    assert r.json() == full.json()


@pytest.mark.parametrize("method", ["GET", "DELETE", "POST"])
@pytest.mark.parametrize("sid", ["A" * 43, "nope", "A" * 44])
def test_unknown_scene_is_404(daemon, validators, method, sid):
    path = f"/v1/scenes/{sid}" + ("/contact" if method == "POST" else "")
    r = requests.request(method, daemon.url(path), timeout=10)
    check_error(validators, r, 404, "unknown_scene")


def test_scene_routes_methods(daemon, validators):
    r = requests.get(daemon.url("/v1/scenes"), timeout=10)
    assert r.status_code == 405 and r.headers["Allow"] == "POST, OPTIONS"
    r = requests.put(daemon.url("/v1/scenes/" + "A" * 43), timeout=10)
    assert r.status_code == 405 and r.headers["Allow"] == "GET, HEAD, DELETE, OPTIONS"
    r = requests.get(daemon.url("/v1/scenes/" + "A" * 43 + "/contact"), timeout=10)
    assert r.status_code == 405 and r.headers["Allow"] == "POST, OPTIONS"
    r = requests.get(daemon.url("/v1/scenes/" + "A" * 43 + "/other"), timeout=10)
    check_error(validators, r, 404, "not_found")


def test_ids_are_unguessable(daemon, paths, validators):
    scene = load(paths, "two_disks")
    ids = [create(daemon, scene, validators)["id"] for _ in range(8)]
    assert len(set(ids)) == 8
    for sid in ids:
        assert len(sid) == 43  # 256 bits of base64url: the schema's pattern checks the alphabet
        assert requests.delete(daemon.url(f"/v1/scenes/{sid}"), timeout=10).status_code == 204
    # 8 ids of 256 random bits: every one of the 64 characters is about equally likely; at least
    # 20 distinct ones among 344 characters (a fixed or counter-like id would fail).
    assert len(set("".join(ids))) >= 20


# ------------------------------------------------------------ concurrency

def test_concurrent_steps_on_one_session_never_interleave(daemon, paths, validators):
    scene = load(paths, "jittered_packing")
    doc = create(daemon, scene, validators)
    pos0 = positions_of(scene)
    rng = np.random.default_rng(5)
    moves = [pos0 + rng.normal(scale=0.003, size=pos0.shape) for _ in range(6)]
    wants = [full_contact(daemon, with_positions(scene, p)) for p in moves]
    failures = []

    def worker(i):
        s = requests.Session()
        for rep in range(5):
            k = (i + rep) % len(moves)
            if (i + rep) % 2:
                r = s.post(daemon.url(f"/v1/scenes/{doc['id']}/contact"),
                           data=moves[k].astype("<f8").tobytes(), headers=BINARY, timeout=60)
                f = np.frombuffer(r.content, dtype="<f8").reshape(-1, 2)
                if r.status_code != 200 or not np.array_equal(f, forces_of(wants[k])):
                    failures.append((i, rep, r.status_code))
            else:
                r = s.post(daemon.url(f"/v1/scenes/{doc['id']}/contact"), json={"positions": moves[k].tolist()},
                           timeout=60)
                if r.status_code != 200 or without_elapsed(r.json()) != without_elapsed(wants[k]):
                    failures.append((i, rep, r.status_code))

    threads = [threading.Thread(target=worker, args=(i,)) for i in range(6)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert failures == []
    assert requests.get(daemon.url(f"/v1/scenes/{doc['id']}"), timeout=10).json()["steps"] == 30


# ------------------------------------------------------------ bounds

def health_sessions(d):
    return requests.get(d.url("/v1/health"), timeout=10).json()["sessions"]


def test_max_sessions_evicts_the_least_recently_used(daemon_factory, paths, validators):
    d = daemon_factory("--max-sessions", "2")
    scene = load(paths, "two_disks")
    a = create(d, scene, validators)["id"]
    b = create(d, scene, validators)["id"]
    assert requests.post(d.url(f"/v1/scenes/{a}/contact"), timeout=10).status_code == 200  # a is now newer than b
    c = create(d, scene, validators)["id"]
    assert requests.post(d.url(f"/v1/scenes/{b}/contact"), timeout=10).status_code == 404
    for sid in (a, c):
        assert requests.post(d.url(f"/v1/scenes/{sid}/contact"), timeout=10).status_code == 200
    h = health_sessions(d)
    assert h["held"] == 2 and h["evicted"] == 1 and h["max"] == 2 and h["created"] == 3


def test_session_memory_budget(daemon_factory, paths, validators):
    scene = load(paths, "jittered_packing")
    probe = daemon_factory()
    sid = create(probe, scene, validators)["id"]
    requests.post(probe.url(f"/v1/scenes/{sid}/contact"), timeout=10)
    one = requests.get(probe.url(f"/v1/scenes/{sid}"), timeout=10).json()["memory_bytes"]
    assert one > 16 * positions_of(scene).size // 2  # at least the positions themselves
    assert health_sessions(probe)["memory_bytes"] == one
    # Room for two and a half: the third makes the idle ones give back their
    # evaluation buffers (issue 23: a warm context is a cache, a session is
    # not); they stay, and step again.
    d = daemon_factory("--session-memory", str(int(2.5 * one)))
    ids = []
    for _ in range(3):
        ids.append(create(d, scene, validators)["id"])
        assert requests.post(d.url(f"/v1/scenes/{ids[-1]}/contact"), timeout=10).status_code == 200
    h = health_sessions(d)
    assert h["held"] == 3 and h["evicted"] == 0 and h["trimmed"] >= 1 and h["memory_bytes"] <= int(2.5 * one), h
    # More: what is left after the buffers is evicted, the least recently used first.
    while health_sessions(d)["evicted"] == 0 and len(ids) < 40:
        ids.append(create(d, scene, validators)["id"])
        assert requests.post(d.url(f"/v1/scenes/{ids[-1]}/contact"), timeout=10).status_code == 200
    h = health_sessions(d)
    assert h["evicted"] >= 1 and h["held"] + h["evicted"] == len(ids) and h["memory_bytes"] <= int(2.5 * one), h
    assert requests.post(d.url(f"/v1/scenes/{ids[0]}/contact"), timeout=10).status_code == 404
    # A scene that alone exceeds the budget is refused, naming the flag.
    tiny = daemon_factory("--session-memory", "10k")
    r = requests.post(tiny.url("/v1/scenes"), json=scene, timeout=10)
    e = check_error(validators, r, 413, "payload_too_large")
    assert "--session-memory" in e["message"]


def test_session_ttl(daemon_factory, paths, validators):
    d = daemon_factory("--session-ttl", "1")
    scene = load(paths, "two_disks")
    sid = create(d, scene, validators)["id"]
    assert create(d, scene, validators)["expires_in_s"] == 1
    time.sleep(0.6)
    assert requests.post(d.url(f"/v1/scenes/{sid}/contact"), timeout=10).status_code == 200  # a use
    time.sleep(0.6)
    assert requests.post(d.url(f"/v1/scenes/{sid}/contact"), timeout=10).status_code == 200  # still alive
    time.sleep(1.5)
    check_error(validators, requests.post(d.url(f"/v1/scenes/{sid}/contact"), timeout=10), 404, "unknown_scene")
    assert health_sessions(d)["expired"] == 2
    assert health_sessions(d)["held"] == 0


def test_a_session_in_use_is_never_evicted(daemon_factory, paths, validators):
    """--max-sessions 1: while a step runs, creating another session answers 503
    (every session is in use), never evicts the busy one."""
    d = daemon_factory("--max-sessions", "1", "--threads", "2")
    big = {"version": 1, "options": {"penalty": 1.0, "search": "brute_force"}, "bodies": []}
    for i in range(40):
        th = np.linspace(0, 2 * np.pi, 200, endpoint=False)
        big["bodies"].append({"id": i, "nodes": np.c_[np.cos(th) + 1.9 * (i % 8),
                                                        np.sin(th) + 1.9 * (i // 8)].tolist()})
    sid = create(d, big, validators)["id"]
    result = {}

    def slow_step():
        result["r"] = requests.post(d.url(f"/v1/scenes/{sid}/contact"), timeout=120)

    saw_busy = False
    for _ in range(5):
        t = threading.Thread(target=slow_step)
        t.start()
        time.sleep(0.05)
        r = requests.post(d.url("/v1/scenes"), json=load(paths, "two_disks"), timeout=60)
        t.join()
        assert result["r"].status_code == 200
        if r.status_code == 503:
            check_error(validators, r, 503, "overloaded")
            assert r.headers["Retry-After"] == "1"
            saw_busy = True
            break
        # The step had finished before the create: it was evicted, which is right for an idle one.
        assert r.status_code == 201
        sid = create(d, big, validators)["id"]
    assert saw_busy
    assert requests.post(d.url(f"/v1/scenes/{sid}/contact"), timeout=120).status_code == 200


def test_kept_candidates_answer_as_a_session_without(daemon, paths, validators):
    """A session keeps a candidate list by default (docs/model.md §15): a walk
    of small steps (replayed), a step past the skin and steps back, answer bit
    for bit as a session created with "keep_candidates": false, and as one
    with a skin of 0 (built every step); a bad skin is a 400 naming it."""
    scene = load(paths, "jittered_packing")
    scene.setdefault("options", {})["outputs"] = ["forces", "energy", "virial", "contacts", "gaps"]
    off = copy.deepcopy(scene)
    off["session"] = {"keep_candidates": False}
    thin = copy.deepcopy(scene)
    thin["session"] = {"skin": 0.0}
    ids = [create(daemon, s, validators)["id"] for s in (scene, off, thin)]
    pos0 = positions_of(scene)
    rng = np.random.default_rng(27)
    scale = float(np.ptp(pos0[:, 0])) * 1e-4
    pos = pos0.copy()
    for step in range(12):
        pos = pos + rng.normal(scale=scale if step != 6 else 100 * scale, size=pos.shape)
        answers = []
        for sid in ids:
            r = step_json(daemon, sid, {"positions": pos.tolist()})
            assert r.status_code == 200, r.text
            answers.append(without_elapsed(r.json()))
        assert answers[0] == answers[1] == answers[2], step
        assert answers[0]["summary"]["contacts"] > 0
    for bad, where in (({"skin": -1}, "/session/skin"), ({"skin": "x"}, "/session/skin"),
                       ({"keep_candidates": 1}, "/session/keep_candidates")):
        s = copy.deepcopy(scene)
        s["session"] = bad
        r = requests.post(daemon.url("/v1/scenes"), json=s, timeout=60)
        assert r.status_code == 400, r.text
        validators["error"].validate(r.json())
        assert r.json()["error"]["pointer"] == where, r.text


def test_json_positions_read_as_the_general_parser_does(daemon, paths, validators):
    """The JSON step's own reader of {"positions": ..., "commit": ...} (one
    pass, no tree) gives the positions the general parser gives: every JSON
    spelling of a number (exponents, signs, -0, subnormals, the largest
    double, whitespace anywhere, the keys in either order) answers as the
    binary step with the same doubles; what is not JSON (01, +1, .5, 1., NaN,
    a trailing comma, a duplicate key) is still a 400 naming its place."""
    scene = load(paths, "two_disks")
    doc = create(daemon, scene, validators)
    pos = positions_of(scene).copy()
    n = len(pos)
    spellings = ["{:.17g}", "{:.17e}", "{:.17E}", "{!r}"]
    for variant in range(4):
        items = []
        for k, (x, y) in enumerate(pos):
            fx = spellings[(k + variant) % 4].format(float(x))
            fy = spellings[(k + 2 * variant + 1) % 4].format(float(y)).replace("e-0", "e-").replace("e+", "E+")
            items.append(f" [ {fx} ,\n{fy}\t] ")
        body = "{\"positions\":[" + ",".join(items) + "]}" if variant % 2 == 0 else \
            "{ \"commit\" : true ,\r\n \"positions\" : [" + ",".join(items) + "] }"
        r = requests.post(daemon.url(f"/v1/scenes/{doc['id']}/contact"), data=body.encode(),
                          headers={"Content-Type": "application/json"}, timeout=60)
        assert r.status_code == 200, r.text
        # (an "options" member: the general parser's way)
        got = step_json(daemon, doc["id"], {"positions": pos.tolist(), "options": {}})
        assert got.status_code == 200, got.text
        assert without_elapsed(r.json()) == without_elapsed(got.json())
    # exact doubles: -0, a subnormal, the largest, one past a tie
    odd = pos.copy()
    odd[0] = [-0.0, pos[0, 1]]
    odd[1] = [pos[1, 0] + 5e-324, pos[1, 1]]
    text = json.dumps({"positions": odd.tolist()})
    r1 = requests.post(daemon.url(f"/v1/scenes/{doc['id']}/contact"), data=text.encode(),
                       headers={"Content-Type": "application/json"}, timeout=60)
    r2 = step_json(daemon, doc["id"], {"positions": odd.tolist(), "commit": True, "options": {}})
    assert r1.status_code == r2.status_code == 200
    assert without_elapsed(r1.json()) == without_elapsed(r2.json())
    first = json.dumps(pos[0].tolist())
    for bad, where in (("01", "/positions/0/0"), ("+1", "/positions/0/0"), (".5", "/positions/0/0"),
                       ("1.", "/positions/0/0"), ("NaN", "/positions/0/0")):
        body = "{\"positions\": [[" + bad + ", 0]" + "".join(", " + json.dumps(p) for p in pos[1:].tolist()) + "]}"
        r = requests.post(daemon.url(f"/v1/scenes/{doc['id']}/contact"), data=body.encode(),
                          headers={"Content-Type": "application/json"}, timeout=60)
        assert r.status_code == 400, (bad, r.text)
        validators["error"].validate(r.json())
    for body in ("{\"positions\": [" + first + "],}", "{\"commit\": true, \"commit\": true, \"positions\": []}",
                 "{\"positions\": [" + ", ".join(json.dumps(p) for p in pos.tolist()) + "]} x"):
        r = requests.post(daemon.url(f"/v1/scenes/{doc['id']}/contact"), data=body.encode(),
                          headers={"Content-Type": "application/json"}, timeout=60)
        assert r.status_code == 400, (body[:80], r.text)
    assert n == len(pos)

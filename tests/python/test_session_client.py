"""The Python client's sessions (`Client.session`, `Session.contact`) against the
real daemon: binary and JSON steps equal full-scene calls bit for bit, positions
as one array or per body, the stored positions, the transparent re-creation
after a 404, and the checks made before anything is sent."""
import json

import numpy as np
import pytest

from conftest import positions_of, with_positions
import requests

ntscontact = pytest.importorskip("ntscontact")
from ntscontact import Client, InvalidScene, NtsError, Scene, Session  # noqa: E402

EXAMPLES = ["two_disks", "jittered_packing", "periodic_packing", "triangle_meshes"]


def load(paths, name):
    return json.loads((paths.examples / f"{name}.json").read_text())




def same_summary(a, b):
    fields = ("contacts", "gaps", "energy", "max_penetration", "loops_reversed", "search_radius", "cell_size",
              "nodes", "surface_nodes", "bodies")
    assert {f: getattr(a, f) for f in fields} == {f: getattr(b, f) for f in fields}
    assert np.array_equal(a.virial, b.virial)


@pytest.fixture
def client(daemon):
    with Client(daemon.base, timeout=60) as c:
        yield c


@pytest.mark.parametrize("name", EXAMPLES)
def test_binary_steps_equal_full_calls(client, paths, name):
    scene = load(paths, name)
    pos0 = positions_of(scene)
    rng = np.random.default_rng(len(name))
    with client.session(scene) as s:
        assert isinstance(s, Session) and s.nodes == len(pos0)
        for _ in range(3):
            pos = pos0 + rng.normal(scale=1e-3, size=pos0.shape)
            got = s.contact(pos, outputs=["forces", "energy", "virial"])
            want = client.contact(with_positions(scene, pos), outputs=["forces", "energy", "virial"])
            f = got.force_array()
            assert f.shape == pos.shape and not f.flags.writeable  # the answer's own buffer
            assert np.array_equal(f, want.force_array())
            for body_id in want.forces:
                assert np.array_equal(got.forces[body_id], want.forces[body_id])
            same_summary(got.summary, want.summary)
        # JSON answers (contacts asked for) of the same step are equal too.
        got = s.contact(pos, outputs=["forces", "contacts", "gaps"])
        want = client.contact(with_positions(scene, pos), outputs=["forces", "contacts", "gaps"])
        assert got.contacts == want.contacts and got.gaps == want.gaps
        assert np.array_equal(got.force_array(), want.force_array())
        assert s.steps == 4 and s.recreated == 0


def test_positions_per_body_and_stored(client, paths):
    scene = load(paths, "jittered_packing")
    pos = positions_of(scene)
    ids = [b["id"] for b in scene["bodies"]]
    n0 = len(scene["bodies"][0]["nodes"])
    with client.session(scene) as s:
        moved = pos.copy()
        moved[:n0] += [0.01, -0.005]
        got = s.contact({ids[0]: moved[:n0]})
        want = client.contact(with_positions(scene, moved))
        assert np.array_equal(got.force_array(), want.force_array())
        # Nothing given: the stored positions (the last step's).
        again = s.contact()
        assert np.array_equal(again.force_array(), want.force_array())
        assert np.array_equal(s.positions(), moved)
        # Options of one step only.
        stiff = s.contact(moved, penalty=250.0, alpha=0.1)
        scene250 = with_positions(scene, moved)
        scene250["options"].update(penalty=250.0, alpha=0.1)
        assert np.array_equal(stiff.force_array(), client.contact(scene250).force_array())
        assert np.array_equal(s.contact().force_array(), want.force_array())


def test_a_scene_object_and_the_stored_positions(client):
    scene = Scene(penalty=50.0, alpha=0.2)
    th = np.linspace(0, 2 * np.pi, 32, endpoint=False)
    scene.add_body(np.c_[np.cos(th), np.sin(th)], id="a")
    scene.add_body(np.c_[np.cos(th) + 1.95, np.sin(th)], id="b")
    with client.session(scene) as s:
        r = s.contact()
        assert r.summary.contacts > 0
        assert np.array_equal(r.force_array(), client.contact(scene).force_array())


def test_recreated_once_after_a_404(client, daemon, paths):
    scene = load(paths, "two_disks")
    pos = positions_of(scene) + 0.002
    with client.session(scene) as s:
        s.contact(pos)
        first = s.id
        # The service loses the session (expired, evicted, restarted: here deleted behind the client's back).
        assert requests.delete(daemon.url(f"/v1/scenes/{first}"), timeout=10).status_code == 204
        got = s.contact()  # no positions: the client sends its own copy to the new session
        assert s.recreated == 1 and s.id != first
        assert np.array_equal(got.force_array(), client.contact(with_positions(scene, pos)).force_array())
        requests.delete(daemon.url(f"/v1/scenes/{s.id}"), timeout=10)
        pos2 = pos - 0.001
        got = s.contact(pos2, outputs=["forces", "contacts"])  # the JSON answer path too
        assert s.recreated == 2
        assert got.contacts == client.contact(with_positions(scene, pos2), outputs=["forces", "contacts"]).contacts


def test_another_daemon_takes_over(daemon_factory, paths):
    """A load balancer sends the step to a daemon that never saw the session."""
    scene = load(paths, "two_disks")
    a, b = daemon_factory(), daemon_factory()
    with Client(a.base, timeout=60) as c:
        s = c.session(scene)
        s.contact()
        c.base_url = b.base
        r = s.contact(positions_of(scene))
        assert s.recreated == 1
        assert r.summary.contacts > 0
        assert requests.get(b.url(f"/v1/scenes/{s.id}"), timeout=10).status_code == 200
        s.close()
        assert requests.get(b.url(f"/v1/scenes/{s.id}"), timeout=10).status_code == 404


def test_a_third_404_is_raised(client, daemon, paths, monkeypatch):
    """Re-created twice within one step at most (a session re-created while its
    daemon was away may be lost again when it returns); a third loss is raised."""
    scene = load(paths, "two_disks")
    s = client.session(scene)
    original = Session._create

    def create_then_lose(self):
        original(self)
        requests.delete(daemon.url(f"/v1/scenes/{self.id}"), timeout=10)

    requests.delete(daemon.url(f"/v1/scenes/{s.id}"), timeout=10)
    monkeypatch.setattr(Session, "_create", create_then_lose)
    with pytest.raises(NtsError) as info:
        s.contact()
    assert info.value.status == 404 and info.value.code == "unknown_scene"
    assert s.recreated == 2


def test_context_manager_deletes(client, daemon, paths):
    with client.session(load(paths, "two_disks")) as s:
        sid = s.id
        assert s.info()["id"] == sid
    assert requests.get(daemon.url(f"/v1/scenes/{sid}"), timeout=10).status_code == 404
    s.close()  # twice is fine
    with pytest.raises(NtsError):
        s.contact()


def test_bad_positions_are_refused(client, paths, daemon):
    """Shapes refused by the client, a non-finite position by the service
    (code and pointer alike): no step counted, the stored positions kept."""
    scene = load(paths, "two_disks")
    pos = positions_of(scene)
    with client.session(scene) as s:
        before = requests.get(daemon.url(f"/v1/scenes/{s.id}"), timeout=10).json()["steps"]
        with pytest.raises(InvalidScene) as e:
            s.contact(pos[:-1])
        assert e.value.pointer == "/positions"
        bad = pos.copy()
        bad[7, 0] = np.inf
        with pytest.raises(InvalidScene) as e:
            s.contact(bad)
        assert e.value.code == "non_finite" and e.value.pointer == "/positions/7"
        assert np.array_equal(s.positions(), pos)
        with pytest.raises(InvalidScene):
            s.contact({scene["bodies"][0]["id"]: pos[:3]})
        for unknown in ("nope", 0, "0"):  # (a KeyError; the ids are "left" and "right")
            with pytest.raises(InvalidScene) as e:
                s.contact({scene["bodies"][0]["id"]: pos[:48], unknown: pos[:3]})
            assert (e.value.code, e.value.pointer) == ("invalid_value", "/positions")
            assert f"body id {unknown!r}" in str(e.value)
        with pytest.raises(InvalidScene):
            s.contact(outputs=["stress"])
        assert requests.get(daemon.url(f"/v1/scenes/{s.id}"), timeout=10).json()["steps"] == before
        # The service's own checks come back typed, with their pointer.
        with pytest.raises(InvalidScene) as e:
            s.contact(pos, alpha=0.9)
        assert e.value.code == "invalid_option" and e.value.pointer == "/options/alpha"


@pytest.mark.parametrize("wire", [True, False])
def test_binary_answers_keep_one_connection(daemon, paths, wire):
    """A binary answer is read whole (one read of its Content-Length, not
    requests' 10 kB chunks) over one kept connection: the client's own
    (``wire``, the default for http://) or urllib3's pool's. 30 binary steps,
    a JSON one between, the session made and deleted, over one connection;
    the answer stays the full call's."""
    scene = json.loads((paths.examples / "two_disks.json").read_text())
    with Client(daemon.base, timeout=60, wire=wire) as client:
        with client.session(scene) as s:
            x = s.positions()
            for k in range(30):
                res = s.contact(x + 1e-6 * k, outputs=["forces"])
                assert res.raw == {}  # the binary answer
                if k == 15:
                    s.contact(x, outputs=["forces", "contacts"])
            full = client.contact(with_positions(scene, x + 1e-6 * 29), outputs=["forces"])
            assert np.array_equal(res.force_array(), full.force_array())
        pools = client.http.adapters["http://"].poolmanager.pools
        in_pool = [pools[k].num_connections for k in pools.keys()]
        if wire:
            assert client._wire is not None and client._wire.connections == 1
            assert client._wire.exchanges == 30 + 1 + 1 + 2 and in_pool == []
        else:
            assert client._wire is None and in_pool == [1]


def test_a_binary_answers_per_body_forces(client, paths):
    """res.forces of a binary answer: every body in scene order, each its rows
    of force_array(), an unknown id a KeyError, as a JSON answer's dict."""
    scene = json.loads((paths.examples / "jittered_packing.json").read_text())
    ids = [b["id"] for b in scene["bodies"]]
    with client.session(scene) as s:
        res = s.contact(outputs=["forces"])
        js = s.contact(outputs=["forces", "contacts"])
    assert res.raw == {} and list(res.forces) == ids == list(js.forces) and len(res.forces) == len(ids)
    for i in ids:
        assert np.array_equal(res.forces[i], js.forces[i])
    assert np.array_equal(np.concatenate([res.forces[i] for i in ids]), res.force_array())
    with pytest.raises(KeyError):
        res.forces["no such body"]
    assert dict(res.forces).keys() == js.forces.keys()


def test_kept_candidates_options_reach_the_session(client, paths):
    """keep_candidates and skin go into the scene's "session" object; a session
    without a list, with a zero skin and with the default answer alike (the
    list changes the time of a step, never its answer); a negative skin is
    refused by the service, naming /session/skin."""
    scene = load(paths, "jittered_packing")
    pos0 = positions_of(scene)
    rng = np.random.default_rng(5)
    with client.session(scene) as a, client.session(scene, keep_candidates=False) as b, \
            client.session(scene, skin=0.0) as c:
        assert json.loads(b._body)["session"] == {"keep_candidates": False}
        assert json.loads(c._body)["session"] == {"skin": 0.0}
        assert "session" not in json.loads(a._body)
        pos = pos0.copy()
        for _ in range(5):
            pos = pos + rng.normal(scale=2e-3, size=pos0.shape)
            got = [s.contact(pos) for s in (a, b, c)]
            for r in got[1:]:
                assert np.array_equal(r.force_array(), got[0].force_array())
                same_summary(r.summary, got[0].summary)
    with pytest.raises(InvalidScene) as e:
        client.session(scene, skin=-1.0)
    assert e.value.pointer == "/session/skin"
    for skin in (float("nan"), float("inf"), -float("inf"), np.float64("nan")):  # (a ValueError of json.dumps)
        with pytest.raises(InvalidScene) as f:
            client.session(scene, skin=skin)
        assert (f.value.code, f.value.pointer, f.value.message) == (e.value.code, e.value.pointer, e.value.message)


def test_steps_skip_requests_machinery_and_fall_back_to_it(daemon, paths):
    """A step goes to requests' own connection pool directly (requests' per-call
    merging and hooks cost a millisecond a step, docs/benchmarks.md): with the
    default client no call reaches ``requests.Session.request``. A client whose
    requests session needs that machinery (a hook, proxies, auth, cookies, its
    own adapter) goes through requests. Both give the full call's answer, bit
    for bit, binary and JSON, with query options and the client's headers."""
    if not hasattr(requests.adapters.HTTPAdapter, "get_connection_with_tls_context"):
        pytest.skip("requests older than 2.32.2: every call goes through requests")
    scene = load(paths, "jittered_packing")
    x = positions_of(scene) + 1e-4

    def steps(c):
        with c.session(scene) as s:
            binary = s.contact(x, outputs=["forces", "energy"], alpha=0.1)
            as_json = s.contact(x, outputs=["forces", "contacts"], alpha=0.1)
            assert binary.raw == {} and as_json.raw != {}
            return binary, as_json

    with Client(daemon.base, timeout=60) as ref:
        full = ref.contact(dict(with_positions(scene, x), options={**scene.get("options", {}), "alpha": 0.1}),
                           outputs=["forces", "contacts"])
    with Client(daemon.base, timeout=60) as direct:
        def refuse(*a, **k):
            raise AssertionError("a step went through requests.Session.request")
        direct.http.request = refuse  # (instance attribute: only this client's)
        got = steps(direct)
    seen = []
    with Client(daemon.base, timeout=60) as hooked:
        hooked.http.hooks["response"].append(lambda r, *a, **k: seen.append(r.request.headers["User-Agent"]))
        got_hooked = steps(hooked)
    assert len(seen) == 4 and all(ua.startswith("ntscontact-python/") for ua in seen)  # create, 2 steps, delete
    for b, j in (got, got_hooked):
        assert np.array_equal(b.force_array(), full.force_array())
        assert np.array_equal(j.force_array(), full.force_array()) and j.contacts == full.contacts
        assert b.summary.energy == full.summary.energy


def test_a_step_to_a_daemon_gone_is_service_unavailable(daemon_factory, paths):
    """The direct path says a refused connection as requests' did: unreachable,
    no status; a session whose daemon is gone does not hang."""
    d = daemon_factory()
    with Client(d.base, timeout=10, retries=1, backoff=0.0) as c:
        s = c.session(load(paths, "two_disks"))
        s.contact()
        d.stop()
        with pytest.raises(ntscontact.ServiceUnavailable) as ei:
            s.contact()
        assert ei.value.status is None and ei.value.code == "unreachable"


def test_the_direct_path_keeps_requests_semantics():
    """What requests did and the direct path must too: a cookie the service
    sets is sent back (a load balancer's stickiness), a redirect is followed,
    credentials in the URL are sent, a path prefix is kept."""
    import http.server
    import socketserver
    import threading

    seen = []

    class H(http.server.BaseHTTPRequestHandler):
        protocol_version = "HTTP/1.1"

        def log_message(self, *a):
            pass

        def do_GET(self):
            seen.append((self.path, self.headers.get("Cookie"), self.headers.get("Authorization")))
            if self.path.endswith("/old/v1/health"):
                self.send_response(307)
                self.send_header("Location", self.path.replace("/old/", "/new/"))
                self.send_header("Content-Length", "0")
                self.end_headers()
                return
            body = b'{"status": "ok"}'
            self.send_response(200)
            self.send_header("Set-Cookie", "route=a1; Path=/")
            self.send_header("Content-Type", "application/json")
            self.send_header("Content-Length", str(len(body)))
            self.end_headers()
            self.wfile.write(body)

    srv = socketserver.ThreadingTCPServer(("127.0.0.1", 0), H)
    srv.daemon_threads = True
    threading.Thread(target=srv.serve_forever, daemon=True).start()
    port = srv.server_address[1]
    try:
        with Client(f"http://127.0.0.1:{port}/api", timeout=10) as c:
            assert c.health()["status"] == "ok"
            assert c.health()["status"] == "ok"
            assert seen[0] == ("/api/v1/health", None, None) and seen[1][1] == "route=a1"
        seen.clear()
        with Client(f"http://127.0.0.1:{port}/old", timeout=10) as c:
            assert c.health()["status"] == "ok"
            assert [p for p, _, _ in seen] == ["/old/v1/health", "/new/v1/health"]
        seen.clear()
        with Client(f"http://u:pw@127.0.0.1:{port}", timeout=10) as c:
            assert c.health()["status"] == "ok"
            assert seen[0][2] is not None and seen[0][2].startswith("Basic ")
    finally:
        srv.shutdown()
        srv.server_close()

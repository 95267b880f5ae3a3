"""Contact surfaces through every door (docs/model.md §13, issue 25 §1): a
body's "surface" validates against the scene schema; the CLI, POST
/v1/contact and a session's JSON and binary steps give the patch test's
uniform pressure (corner nodes included) and the same bits; a session that
builds its scene anew (a body mirrored) keeps its surfaces; every bad surface
gets its code and JSON pointer from the CLI (exit 3) and the daemon (400)."""
import json
import subprocess

import jsonschema
import numpy as np
import pytest
import requests

from conftest import CLI, positions_of, run_cli_json, start_daemon, with_positions

BINARY = {"Content-Type": "application/octet-stream", "Accept": "application/octet-stream"}


def block(x0, y0, w, h, nb, nt):
    """A counter-clockwise block: nb nodes along the bottom (left to right),
    nt along the top (right to left); no side nodes."""
    bottom = [[x0 + w * i / (nb - 1), y0] for i in range(nb)]
    top = [[x0 + w * (nt - 1 - i) / (nt - 1), y0 + h] for i in range(nt)]
    return bottom + top


def stack(nlo=5, nup=7, alpha=0.2, surfaces=True, one_pass=False, overlap=0.01):
    """Two blocks of width 1 with flush sides, the upper `overlap` into the
    lower; the lower's top edge and the upper's bottom edge as surfaces."""
    lo = {"id": "lower", "nodes": block(0.0, 0.0, 1.0, 1.0, 2, nlo)}
    up = {"id": "upper", "nodes": block(0.0, 1.0 - overlap, 1.0, 1.0, nup, 2)}
    if surfaces:
        lo["surface"] = [[2 + i, 3 + i] for i in range(nlo - 1)]
        up["surface"] = [[i + 1, i] for i in range(nup - 1)]   # the other direction: either is fine
    if one_pass:
        lo["role"] = "master"
    return {"version": 1,
            "options": {"penalty": 300.0, "alpha": alpha, "penalty_scaling": "length",
                        "outputs": ["forces", "energy", "contacts", "pressure"]},
            "bodies": [lo, up]}


def interface_nodes(scene, body):
    """The nodes on a body's surface (the ends of its pairs)."""
    return sorted({k for pair in scene["bodies"][body]["surface"] for k in pair})


@pytest.mark.parametrize("alpha", [0.0, 0.2])
@pytest.mark.parametrize("one_pass", [False, True])
def test_patch_pressure_is_uniform_through_the_cli(schemas, alpha, one_pass):
    scene = stack(alpha=alpha, one_pass=one_pass)
    jsonschema.Draft202012Validator(schemas["scene"]).validate(scene)
    res = run_cli_json(scene)
    jsonschema.Draft202012Validator(schemas["result"]).validate(res)
    p = 300.0 * 0.01
    slaves = [1] if one_pass else [0, 1]
    for b in slaves:
        pressure = res["bodies"][b]["pressure"]
        for k in interface_nodes(scene, b):
            assert pressure[k] == pytest.approx(p, rel=1e-12), (b, k)
    assert res["summary"]["contacts"] == sum(len(interface_nodes(scene, b)) for b in slaves)
    up = np.asarray(res["bodies"][1]["forces"]).sum(axis=0)
    assert up == pytest.approx([0.0, p * 1.0 * len(slaves)], rel=1e-12, abs=1e-12)


def test_without_surfaces_the_corners_get_nothing():
    """The flush stack without surfaces (docs/model.md §13): four-node squares
    give no contact at all; finer edges leave the corner nodes out."""
    coarse = stack(nlo=2, nup=2, surfaces=False)
    assert run_cli_json(coarse)["summary"]["contacts"] == 0
    fine = run_cli_json(stack(surfaces=False))
    assert fine["summary"]["contacts"] == 3 + 5
    assert fine["bodies"][1]["pressure"][0] == 0.0 and fine["bodies"][1]["pressure"][6] == 0.0


def test_a_whole_surface_answers_as_none():
    scene = stack(surfaces=False)
    plain = run_cli_json(scene)
    for b in scene["bodies"]:
        n = len(b["nodes"])
        b["surface"] = [[k, (k + 1) % n] for k in range(n)][::-1]
    whole = run_cli_json(scene)
    plain["summary"].pop("elapsed_ms", None)
    whole["summary"].pop("elapsed_ms", None)
    assert whole == plain


@pytest.fixture(scope="module")
def daemon(paths, tmp_path_factory):
    d = start_daemon(paths.bin / "ntscontactd", tmp_path_factory.mktemp("surfaces") / "daemon.log", "--threads", "2")
    yield d
    assert d.stop() == 0, d.log()[-2000:]


def test_http_and_sessions_agree_bit_for_bit(daemon):
    scene = stack()
    full = requests.post(daemon.url("/v1/contact"), json=scene, timeout=60).json()
    cli = run_cli_json(scene)
    for doc in (full, cli):
        doc["summary"].pop("elapsed_ms", None)
    assert full == cli
    r = requests.post(daemon.url("/v1/scenes"), json=scene, timeout=60)
    assert r.status_code == 201, r.text
    sid = r.json()["id"]
    pos0 = positions_of(scene)
    rng = np.random.default_rng(7)
    for _ in range(3):
        pos = pos0 + rng.normal(scale=2e-3, size=pos0.shape)
        # the session measures tributary lengths at its first positions: give them as the reference
        ref_scene = with_positions(scene, pos)
        for b, src in zip(ref_scene["bodies"], scene["bodies"]):
            b["reference"] = src["nodes"]
        want = requests.post(daemon.url("/v1/contact"), json=ref_scene, timeout=60).json()
        got = requests.post(daemon.url(f"/v1/scenes/{sid}/contact"), json={"positions": pos.tolist()},
                            timeout=60).json()
        for doc in (want, got):
            doc["summary"].pop("elapsed_ms", None)
        assert got == want
        b = requests.post(daemon.url(f"/v1/scenes/{sid}/contact"), data=pos.astype("<f8").tobytes(),
                          headers=BINARY, timeout=60)
        assert b.status_code == 200, b.text
        # forces (2N doubles), then the pressure (N) that the scene's outputs ask for
        answer = np.frombuffer(b.content, dtype="<f8")
        assert len(answer) == 3 * len(pos)
        assert np.array_equal(answer[:2 * len(pos)].reshape(-1, 2),
                              np.concatenate([np.asarray(x["forces"]) for x in want["bodies"]]))
        assert np.array_equal(answer[2 * len(pos):], np.concatenate([x["pressure"] for x in want["bodies"]]))
        assert float(b.headers["NTS-Energy"]) == want["summary"]["energy"]
        assert int(b.headers["NTS-Contacts"]) == want["summary"]["contacts"]
    # A step that turns the upper block over (mirrored) builds the scene anew: its surface stays.
    pos = pos0.copy()
    n0 = len(scene["bodies"][0]["nodes"])
    pos[n0:, 0] = 1.0 - pos[n0:, 0]
    got = requests.post(daemon.url(f"/v1/scenes/{sid}/contact"), json={"positions": pos.tolist()}, timeout=60).json()
    assert got["summary"]["loops_reversed"] == 1
    assert got["summary"]["contacts"] == 5 + 7
    for b in (0, 1):
        for k in interface_nodes(scene, b):
            assert got["bodies"][b]["pressure"][k] == pytest.approx(3.0, rel=1e-12)
    requests.delete(daemon.url(f"/v1/scenes/{sid}"), timeout=60)


def cli_error(doc):
    r = subprocess.run([str(CLI), "-"], input=json.dumps(doc).encode(), capture_output=True, timeout=60)
    return r.returncode, r.stderr.decode()


BAD = [
    # (surface of the upper block, code, pointer)
    ([[0, 2]], "invalid_surface", "/bodies/1/surface/0"),            # not a segment (two bottom nodes apart)
    ([[0, 1], [1, 0]], "invalid_surface", "/bodies/1/surface/1"),    # the same segment twice
    ([[0, 1], [3, 3]], "invalid_surface", "/bodies/1/surface/1"),    # one node twice
    ([[0, 1], [2, 9]], "index_out_of_range", "/bodies/1/surface/1/1"),
    ([[-1, 0]], "index_out_of_range", "/bodies/1/surface/0/0"),
    ([[0, 1.5]], "invalid_value", "/bodies/1/surface/0/1"),
    ([[0, "1"]], "invalid_type", "/bodies/1/surface/0/1"),
    ([[0, 1, 2]], "invalid_value", "/bodies/1/surface/0/2"),
    ([[0]], "invalid_value", "/bodies/1/surface/0"),
    ([0, 1], "invalid_type", "/bodies/1/surface/0"),
    ({"0": 1}, "invalid_type", "/bodies/1/surface"),
    ([[k, k + 1] for k in range(10)], "invalid_value", "/bodies/1/surface"),  # more pairs than nodes
]


@pytest.mark.parametrize("surface,code,pointer", BAD)
def test_bad_surfaces_are_named(daemon, schemas, surface, code, pointer):
    scene = stack()
    scene["bodies"][1]["surface"] = surface
    rc, err = cli_error(scene)
    assert rc == 3, err
    assert err.startswith(f'ntscontact: {code} at "{pointer}"'), err
    r = requests.post(daemon.url("/v1/contact"), json=scene, timeout=60)
    assert r.status_code == 400
    doc = r.json()
    jsonschema.Draft202012Validator(schemas["error"]).validate(doc)
    assert (doc["error"]["code"], doc["error"]["pointer"]) == (code, pointer)


def test_a_mesh_body_names_its_boundary():
    """A body given by triangles: its surface pairs are edges of the mesh's
    boundary; an inner edge is refused."""
    nodes = [[0, 0], [1, 0], [2, 0], [2, 1], [1, 1], [0, 1]]
    tris = [[0, 1, 4], [0, 4, 5], [1, 2, 3], [1, 3, 4]]
    floor = {"id": "floor", "nodes": [[-1, -2], [3, -2], [3, 0.01], [-1, 0.01]], "role": "master", "alpha": 0}
    mesh = {"id": "mesh", "nodes": nodes, "triangles": tris, "surface": [[0, 1], [2, 1]]}
    scene = {"version": 1, "options": {"penalty": 100, "alpha": 0.2, "outputs": ["contacts"]}, "bodies": [floor, mesh]}
    res = run_cli_json(scene)
    assert sorted(c["slave"]["node"] for c in res["contacts"]) == [0, 1, 2]
    mesh["surface"] = [[0, 1], [1, 4]]          # 1-4 is inside the mesh
    rc, err = cli_error(scene)
    assert rc == 3 and err.startswith('ntscontact: invalid_surface at "/bodies/1/surface/1"'), err

"""The tangent through every door: `outputs: ["stiffness"]` in the CLI, over
HTTP (full scene, session JSON and session binary), and `Result.stiffness` in
Python; valid against result.schema.json, symmetric, the derivative of the
forces, and the same triplets whichever door."""
import json
import subprocess

import jsonschema
import numpy as np
import pytest
import requests

from conftest import CLI, run_cli_json

ntscontact = pytest.importorskip("ntscontact")
scipy_sparse = pytest.importorskip("scipy.sparse")

run = run_cli_json


def two_disks():
    t = 2 * np.pi * np.arange(20) / 20
    s = 2 * np.pi * (np.arange(14) + 0.3) / 14
    return {"version": 1, "options": {"penalty": 1000.0, "alpha": 0.2, "search_radius": 0.3},
            "bodies": [{"id": "a", "nodes": np.c_[np.cos(t), np.sin(t)].tolist()},
                       {"id": "b", "nodes": np.c_[1.93 + np.cos(s), 0.07 + np.sin(s)].tolist()}]}


def dense(k):
    K = np.zeros((k["size"], k["size"]))
    np.add.at(K, (np.array(k["rows"]), np.array(k["cols"])), np.array(k["values"]))
    return K


def test_cli_stiffness_is_the_derivative_of_the_forces(schemas):
    doc = two_disks()
    out = run(doc, "--outputs", "forces,stiffness")
    jsonschema.validate(out, schemas["result"])
    K = dense(out["stiffness"])
    assert K.shape == (68, 68) and np.abs(K).max() > 0
    assert np.abs(K - K.T).max() <= 1e-13 * np.abs(K).max()
    x = np.concatenate([np.array(b["nodes"]) for b in doc["bodies"]]).ravel()
    h = 1e-6
    for j in np.flatnonzero(np.abs(K).sum(axis=0))[:12]:  # dofs that take part in a contact
        f = []
        for sign in (1, -1):
            xj = x.copy()
            xj[j] += sign * h
            moved = json.loads(json.dumps(doc))
            moved["bodies"][0]["nodes"] = xj[:40].reshape(-1, 2).tolist()
            moved["bodies"][1]["nodes"] = xj[40:].reshape(-1, 2).tolist()
            res = run(moved, "--outputs", "forces")
            f.append(np.concatenate([np.array(b["forces"]) for b in res["bodies"]]).ravel())
        fd = -(f[0] - f[1]) / (2 * h)
        assert np.abs(fd - K[:, j]).max() <= 1e-6 * np.abs(K).max()


def test_http_doors_agree(daemon):
    doc = two_disks()
    doc["options"]["outputs"] = ["forces", "stiffness"]
    cli = run(doc)
    r = requests.post(daemon.url("/v1/contact"), json=doc, timeout=30)
    assert r.json()["stiffness"] == cli["stiffness"]
    with ntscontact.Client(daemon.base, timeout=30) as c, c.session(doc) as s:
        x = s.positions()
        binary = s.contact(x, outputs=["forces", "stiffness"])   # raw triplets after the forces
        js = s.contact(x, outputs=["forces", "stiffness", "contacts"])  # the JSON answer
        rows, cols, values, size = binary.stiffness_triplets()
        assert size == 68
        assert rows.tolist() == cli["stiffness"]["rows"] and cols.tolist() == cli["stiffness"]["cols"]
        assert values.tolist() == cli["stiffness"]["values"]
        K = binary.stiffness
        assert isinstance(K, scipy_sparse.csr_matrix) and K.shape == (68, 68)
        assert np.array_equal(K.toarray(), dense(cli["stiffness"]))
        assert (js.stiffness != K).nnz == 0
        full = c.contact(ntscontact.Scene.from_dict(doc), outputs=["stiffness"])
        assert (full.stiffness != K).nnz == 0
    with pytest.raises(KeyError):  # not asked for: a clear error
        ntscontact.Result.from_dict({k: v for k, v in cli.items() if k != "stiffness"}).stiffness_triplets()


def test_binary_layout_over_raw_http(daemon):
    doc = two_disks()
    sid = requests.post(daemon.url("/v1/scenes"), json=doc, timeout=30).json()["id"]
    x = np.concatenate([np.array(b["nodes"]) for b in doc["bodies"]])
    r = requests.post(daemon.url(f"/v1/scenes/{sid}/contact"), data=x.astype("<f8").tobytes(),
                      params={"outputs": "forces,stiffness"},
                      headers={"Content-Type": "application/octet-stream", "Accept": "application/octet-stream"},
                      timeout=30)
    n, m = len(x), int(r.headers["NTS-Stiffness-Triplets"])
    assert m > 0 and len(r.content) == 16 * n + 16 * m
    rows = np.frombuffer(r.content, "<i4", count=m, offset=16 * n)
    values = np.frombuffer(r.content, "<f8", count=m, offset=16 * n + 8 * m)
    want = run(doc, "--outputs", "stiffness")["stiffness"]
    assert rows.tolist() == want["rows"] and values.tolist() == want["values"]
    # Without stiffness in the outputs, the binary answer is the forces alone.
    r = requests.post(daemon.url(f"/v1/scenes/{sid}/contact"), data=x.astype("<f8").tobytes(),
                      headers={"Content-Type": "application/octet-stream", "Accept": "application/octet-stream"},
                      timeout=30)
    assert r.headers["NTS-Stiffness-Triplets"] == "0" and len(r.content) == 16 * n


def test_no_active_contact_gives_the_empty_matrix_from_every_door(daemon, tmp_path):
    """Asked for and no contact active: the empty 2N x 2N tangent, whichever
    door; a solver loop gets a matrix, never a KeyError (a binary session step
    used to raise one, while the stateless call gave the empty matrix)."""
    doc = two_disks()
    doc["bodies"][1]["nodes"] = (np.array(doc["bodies"][1]["nodes"]) + [5.0, 0.0]).tolist()  # apart
    n = sum(len(b["nodes"]) for b in doc["bodies"])
    cli = run(doc, "--outputs", "forces,stiffness")
    assert cli["summary"]["contacts"] == 0
    assert cli["stiffness"] == {"size": 2 * n, "rows": [], "cols": [], "values": []}
    frames = tmp_path / "frames.bin"
    x = np.concatenate([np.array(b["nodes"]) for b in doc["bodies"]])
    frames.write_bytes(x.astype("<f8").tobytes())
    scene = tmp_path / "scene.json"
    scene.write_text(json.dumps(doc))
    r = subprocess.run([str(CLI), "--frames", str(frames), "--outputs", "forces,stiffness", str(scene)],
                       capture_output=True, timeout=60)
    assert r.returncode == 0, r.stderr.decode()
    assert json.loads(r.stdout)["stiffness"] == cli["stiffness"]
    with ntscontact.Client(daemon.base, timeout=30) as c, c.session(doc) as s:
        results = [c.contact(ntscontact.Scene.from_dict(doc), outputs=["forces", "stiffness"]),  # stateless
                   s.contact(x, outputs=["forces", "stiffness"]),                              # binary step
                   s.contact(x, outputs=["forces", "stiffness", "contacts"]),                  # JSON step
                   s.contact(outputs=["stiffness"])]                                           # stored positions
        for res in results:
            assert res.summary.contacts == 0
            rows, cols, values, size = res.stiffness_triplets()
            assert size == 2 * n and len(rows) == len(cols) == len(values) == 0
            K = res.stiffness
            assert K.shape == (2 * n, 2 * n) and K.nnz == 0
        # Not asked for, through a binary step too: still a clear error.
        with pytest.raises(KeyError):
            s.contact(x, outputs=["forces"]).stiffness_triplets()

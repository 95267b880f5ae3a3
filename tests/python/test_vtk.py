"""`ntscontact --vtk FILE.vtu`: the result as a VTK XML unstructured grid that a
VTK reader (meshio here) reads back with the surfaces, forces, contacts, gaps
and normals of the JSON result, exactly."""
import json
import os
import pathlib
import subprocess
import xml.etree.ElementTree as ET

import numpy as np
import pytest

meshio = pytest.importorskip("meshio")

REPO = pathlib.Path(__file__).resolve().parents[2]
CLI = pathlib.Path(os.environ.get("NTS_BUILD_DIR", str(REPO / "build"))) / "bin" / "ntscontact"
EXAMPLES = ["two_disks", "jittered_packing", "periodic_packing", "triangle_meshes"]


def run(*args, stdin=None):
    return subprocess.run([str(CLI), *map(str, args)], input=stdin, capture_output=True, timeout=120)


def check_against(mesh, scene, result):
    nodes = np.concatenate([np.asarray(b["nodes"], dtype=float).reshape(-1, 2) for b in scene["bodies"]])
    contacts = result.get("contacts", [])
    n, c = len(nodes), len(contacts)
    surface = result["summary"]["surface_nodes"]
    assert mesh.points.shape == (n + c, 3)
    assert np.array_equal(mesh.points[:n, :2], nodes) and not mesh.points[:, 2].any()
    lines = np.concatenate([blk.data for blk in mesh.cells if blk.type == "line"])
    assert lines.shape == (surface + c, 2)
    forces = np.concatenate([np.asarray(b["forces"], dtype=float).reshape(-1, 2) for b in result["bodies"]])
    assert np.array_equal(mesh.point_data["force"][:n, :2], forces)
    kind = np.concatenate(mesh.cell_data["kind"])
    gap = np.concatenate(mesh.cell_data["gap"])
    normal = np.concatenate(mesh.cell_data["normal"])
    assert (kind[:surface] == 0).all() and (kind[surface:] == 1).all()
    assert np.allclose(np.hypot(normal[:, 0], normal[:, 1]), 1.0, atol=1e-12)
    # Each surface cell joins two nodes of one body; every node of a loop starts exactly one segment.
    body = np.concatenate(mesh.cell_data["body"])
    node_body = mesh.point_data["body"]
    assert (node_body[lines[:surface, 0]] == body[:surface]).all()
    assert (node_body[lines[:surface, 1]] == body[:surface]).all()
    assert len(set(lines[:surface, 0])) == surface
    for i, ct in enumerate(contacts):
        assert gap[surface + i] == ct["gap"]
        assert np.array_equal(mesh.points[n + i, :2], ct["point"])
        assert np.array_equal(normal[surface + i, :2], ct["normal"])
        assert lines[surface + i, 1] == n + i
    assert mesh.field_data["energy"].ravel()[0] == result["summary"]["energy"]
    assert list(mesh.field_data["virial"].ravel()) == [result["summary"]["virial"][k] for k in ("xx", "yy", "xy")]


@pytest.mark.parametrize("name", EXAMPLES)
def test_vtk_reads_back_with_the_result(tmp_path, name):
    scene_path = REPO / "examples" / f"{name}.json"
    out = tmp_path / "out.vtu"
    r = run("--vtk", out, "--outputs", "forces,contacts", scene_path)
    assert r.returncode == 0, r.stderr
    result = json.loads(r.stdout)
    assert result["summary"]["contacts"] > 0
    check_against(meshio.read(out), json.loads(scene_path.read_text()), result)


def test_vtk_does_not_change_the_json_answer(tmp_path):
    scene_path = REPO / "examples" / "two_disks.json"
    plain = run("--outputs", "forces", scene_path)
    with_vtk = run("--vtk", tmp_path / "x.vtu", "--outputs", "forces", scene_path)
    strip = lambda d: {**d, "summary": {k: v for k, v in d["summary"].items() if k != "elapsed_ms"}}  # noqa: E731
    assert strip(json.loads(plain.stdout)) == strip(json.loads(with_vtk.stdout))
    assert "contacts" not in json.loads(with_vtk.stdout)  # not asked for, though the VTK file has them


def test_vtk_series_with_frames(tmp_path):
    scene_path = REPO / "examples" / "two_disks.json"
    scene = json.loads(scene_path.read_text())
    pos = np.concatenate([np.asarray(b["nodes"], dtype=float) for b in scene["bodies"]])
    frames = [pos + 0.001 * k for k in range(3)]
    fpath = tmp_path / "frames.bin"
    fpath.write_bytes(b"".join(f.astype("<f8").tobytes() for f in frames))
    r = run("--frames", fpath, "--vtk", tmp_path / "series.vtu", "--outputs", "forces,contacts", scene_path)
    assert r.returncode == 0, r.stderr
    results = [json.loads(line) for line in r.stdout.decode().splitlines()]
    pvd = ET.parse(tmp_path / "series.pvd").getroot()
    files = [d.get("file") for d in pvd.iter("DataSet")]
    assert files == [f"series_{k:06d}.vtu" for k in range(3)]
    assert [d.get("timestep") for d in pvd.iter("DataSet")] == ["0", "1", "2"]
    for k, f in enumerate(files):
        moved = json.loads(json.dumps(scene))
        i = 0
        for b in moved["bodies"]:
            b["nodes"] = frames[k][i:i + len(b["nodes"])].tolist()
            i += len(b["nodes"])
        check_against(meshio.read(tmp_path / f), moved, results[k])


def test_vtk_usage_errors(tmp_path):
    scene_path = REPO / "examples" / "two_disks.json"
    assert run("--vtk", tmp_path / "x.vtp", scene_path).returncode == 2
    assert run("--vtk", tmp_path / "x.vtu", "--validate", scene_path).returncode == 2
    r = run("--vtk", tmp_path / "missing-dir" / "x.vtu", scene_path)
    assert r.returncode == 2 and b"cannot write" in r.stderr

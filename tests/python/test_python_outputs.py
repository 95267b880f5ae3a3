"""The Python helpers for FEM users: Result.to_vtk (the C tool's layout),
plot, contact_arrays, forces back on the mesh through the convert map, and the
Python boundary extraction equal to the C one."""
import json
import os
import pathlib
import subprocess

import numpy as np
import pytest

ntscontact = pytest.importorskip("ntscontact")
meshio = pytest.importorskip("meshio")
from ntscontact.mesh import disk_mesh  # noqa: E402

REPO = pathlib.Path(__file__).resolve().parents[2]
CLI = pathlib.Path(os.environ.get("NTS_BUILD_DIR", str(REPO / "build"))) / "bin" / "ntscontact"
EXAMPLES = ["two_disks", "jittered_packing", "triangle_meshes"]


@pytest.fixture
def client(daemon):
    with ntscontact.Client(daemon.base, timeout=60) as c:
        yield c


def partial_surfaces_scene():
    """Contact surfaces (docs/model.md §13) of every kind: two loop bodies
    pressed together, each with part of its boundary (the upper one given
    clockwise: the service turns it), a triangle mesh with two segments of its
    boundary, a body with an empty surface and one with none."""
    s = ntscontact.Scene(penalty=100.0, alpha=0.2, penalty_scaling="length")
    s.add_body([[0, 0], [1, 0], [1, 0.5], [1, 1], [0.5, 1], [0, 1], [0, 0.5]], id="low",
               surface=[[2, 3], [3, 4], [5, 4]])
    s.add_body([[0, 2], [1, 2], [1, 0.98], [0.5, 0.98], [0, 0.98]], id="up", surface=[[2, 3], [4, 3]])
    pts, tri = disk_mesh(0.3, 2, 1.25, 0.5)
    s.add_body(pts, triangles=tri, id="disk", surface=[[13, 14], [15, 14]])
    s.add_body([[3, 0], [4, 0], [4, 1], [3, 1]], id="none", surface=[])
    s.add_body([[1.05, 1.0], [1.6, 1.0], [1.6, 1.3]], id="whole")
    return s


@pytest.mark.parametrize("name", EXAMPLES + ["partial_surfaces"])
def test_to_vtk_equals_the_c_tool(client, tmp_path, name):
    if name == "partial_surfaces":
        path = tmp_path / "scene.json"
        partial_surfaces_scene().save(path)
    else:
        path = REPO / "examples" / f"{name}.json"
    scene = ntscontact.Scene.load(path)
    res = client.contact(scene, outputs=["forces", "contacts"])
    if name == "partial_surfaces":
        assert res.summary.contacts > 0
    res.to_vtk(tmp_path / "py.vtu")
    r = subprocess.run([str(CLI), "--vtk", str(tmp_path / "c.vtu"), "--outputs", "forces,contacts", str(path)],
                       capture_output=True, timeout=60)
    assert r.returncode == 0
    a, b = meshio.read(tmp_path / "py.vtu"), meshio.read(tmp_path / "c.vtu")
    assert np.array_equal(a.points, b.points)
    assert np.array_equal(a.point_data["force"], b.point_data["force"])
    assert np.array_equal(a.point_data["body"], b.point_data["body"])
    for key in ("kind", "gap", "contact_kind", "contact_force", "master_body"):
        assert np.array_equal(np.concatenate(a.cell_data[key]), np.concatenate(b.cell_data[key])), key
    la = np.concatenate([blk.data for blk in a.cells])
    lb = np.concatenate([blk.data for blk in b.cells])
    # the same segments (a loop may start elsewhere: compare as sets) and the same contact lines
    surf = int((np.concatenate(b.cell_data["kind"]) == 0).sum())
    assert {tuple(x) for x in la[:surf]} == {tuple(x) for x in lb[:surf]}
    assert np.array_equal(la[surf:], lb[surf:])
    assert np.allclose(np.concatenate(a.cell_data["normal"])[surf:], np.concatenate(b.cell_data["normal"])[surf:])
    # each segment on its body's contact surface (1) or off it (0), as the C tool says; -1 for contacts
    fa, fb = np.concatenate(a.cell_data["surface"]).ravel(), np.concatenate(b.cell_data["surface"]).ravel()
    assert {(*x, f) for x, f in zip(map(tuple, la[:surf]), fa[:surf])} == \
           {(*x, f) for x, f in zip(map(tuple, lb[:surf]), fb[:surf])}
    assert (fa[surf:] == -1).all() and (fb[surf:] == -1).all()
    on = int(fb[:surf].sum())
    if name == "partial_surfaces":
        assert 0 < on == 3 + 2 + 2 + 0 + 3 < surf
    else:
        assert on == surf


def test_session_results_know_their_positions(client, tmp_path):
    scene = ntscontact.Scene.load(REPO / "examples" / "two_disks.json")
    with client.session(scene) as s:
        x = s.positions() + 0.01
        res = s.contact(x, outputs=["forces", "contacts"])
    res.to_vtk(tmp_path / "s.vtu")
    m = meshio.read(tmp_path / "s.vtu")
    assert np.array_equal(m.points[:len(x), :2], x)


def test_plot_draws_the_smoothed_bodies(client, tmp_path):
    matplotlib = pytest.importorskip("matplotlib")
    matplotlib.use("Agg")
    scene = ntscontact.Scene.load(REPO / "examples" / "two_disks.json")
    res = client.contact(scene, outputs=["forces"])
    ax = ntscontact.plot(scene, res)
    assert len(ax.lines) >= 4  # two outlines, two node markers
    outline = ax.lines[0].get_xydata()
    assert len(outline) > 48 * 7  # each corner sampled along its polynomial
    ax.figure.savefig(tmp_path / "p.png")
    assert (tmp_path / "p.png").stat().st_size > 1000


def test_contact_arrays_are_complete(client):
    scene = ntscontact.Scene.load(REPO / "examples" / "jittered_packing.json")
    res = client.contact(scene, outputs=["forces", "contacts"])
    a = res.contact_arrays()
    m = len(res.contacts)
    assert m > 0
    for key, shape in (("slave_node", (m,)), ("master_nodes", (m, 3)), ("weights", (m, 3)), ("kind", (m,)),
                       ("gap", (m,)), ("normal", (m, 2)), ("force", (m, 2)), ("virial", (m, 3)),
                       ("slave_body_index", (m,)), ("master_body_index", (m,)), ("xi", (m,))):
        assert a[key].shape == shape, key
    assert np.allclose(a["weights"].sum(axis=1), 1.0)
    ids = res.body_ids
    for k, c in enumerate(res.contacts):
        assert ids[a["slave_body_index"][k]] == c.slave_body and ids[a["master_body_index"][k]] == c.master_body
        assert a["kind"][k] == {"segment": 0, "corner": 1, "vertex": 2}[c.kind]
        assert list(a["master_nodes"][k][:len(c.master_nodes)]) == list(c.master_nodes)


def _two_square_mesh():
    """Two 3x3-node unit squares of triangles, the second 0.05 into the first."""
    pts, tris = [], []
    for ox in (0.0, 0.95):
        base = len(pts)
        for j in range(3):
            for i in range(3):
                pts.append([ox + 0.5 * i, 0.5 * j, 0.0])
        for j in range(2):
            for i in range(2):
                v = base + 3 * j + i
                tris += [[v, v + 1, v + 4], [v, v + 4, v + 3]]
    # an unused point, so that mesh points and nodes differ
    pts.append([9.0, 9.0, 0.0])
    return meshio.Mesh(np.array(pts), [("triangle", np.array(tris))])


def test_convert_keeps_the_map_and_forces_go_back_on_the_mesh(client, tmp_path):
    mesh = _two_square_mesh()
    mesh.write(tmp_path / "m.vtu")
    r = subprocess.run([str(REPO / ".venv" / "bin" / "python"), "-m", "ntscontact", "convert", str(tmp_path / "m.vtu"),
                        "-o", str(tmp_path / "s.json"), "--penalty", "100", "--alpha", "0.2"], capture_output=True,
                       timeout=60)
    assert r.returncode == 0, r.stderr
    doc = json.loads((tmp_path / "s.json").read_text())
    assert [len(b["mesh_points"]) for b in doc["bodies"]] == [9, 9]
    scene = ntscontact.Scene.from_dict(doc)
    res = client.contact(scene, outputs=["forces"])
    f = res.forces_on_mesh(scene, mesh_points=len(mesh.points))
    assert f.shape == (19, 2) and not f[18].any()
    for b in scene:
        assert np.array_equal(f[b.mesh_points], res.forces[b.id])
        assert np.array_equal(np.asarray(mesh.points)[b.mesh_points, :2], b.nodes)
    assert np.allclose(f.sum(axis=0), 0.0, atol=1e-12)
    assert np.abs(f).max() > 0
    # The C side checks the map: one index per node.
    bad = json.loads(json.dumps(doc))
    bad["bodies"][1]["mesh_points"] = bad["bodies"][1]["mesh_points"][:-1]
    r = subprocess.run([str(CLI), "-"], input=json.dumps(bad).encode(), capture_output=True, timeout=60)
    assert r.returncode == 3 and b'"/bodies/1/mesh_points"' in r.stderr


def test_python_boundary_is_the_c_boundary(client):
    """Loops extracted in Python and sent as loops give, bit for bit, the forces
    of the triangles sent to the C extraction."""
    mesh = _two_square_mesh()
    as_tri = ntscontact.mesh.scene_from_mesh(mesh, penalty=100.0, alpha=0.2, boundary="triangles")
    as_loops = ntscontact.mesh.scene_from_mesh(mesh, penalty=100.0, alpha=0.2, boundary="loops")
    a = client.contact(as_tri, outputs=["forces", "contacts"])
    b = client.contact(as_loops, outputs=["forces", "contacts"])
    assert a.summary.contacts == b.summary.contacts > 0
    assert [(c.gap, c.kind) for c in a.contacts] == [(c.gap, c.kind) for c in b.contacts]
    for body in as_loops:
        tri_body = as_tri.body(body.id)
        on = np.concatenate(body.loops)
        # the loop nodes of the loops scene are the boundary nodes of the triangle scene, in mesh-point order
        full = np.zeros((tri_body.node_count, 2))
        full[np.searchsorted(tri_body.mesh_points, body.mesh_points)] = b.forces[body.id]
        assert np.array_equal(full, a.forces[body.id]), body.id
        assert len(on) == body.node_count
    # The same rule as the core: only the connectivity counts, so a sliver
    # triangle (zero area to the last bit) is no fault, and the boundary is
    # the C one: the quadrilateral around both triangles.
    sliver = meshio.Mesh(np.array([[0, 0, 0], [1, 0, 0], [0.5, 1e-17, 0], [0, 1, 0.0]]),
                         [("triangle", np.array([[0, 1, 2], [0, 1, 3]]))])
    tri = ntscontact.mesh.scene_from_mesh(sliver, penalty=1.0)
    loops = ntscontact.mesh.scene_from_mesh(sliver, penalty=1.0, boundary="loops")
    (body,) = list(loops)
    assert [lp.tolist() for lp in body.loops] == [[0, 2, 1, 3]]  # (0, 0), (0.5, 0), (1, 0), (0, 1)
    assert client.contact(tri).summary.surface_nodes == client.contact(loops).summary.surface_nodes == 4


def test_one_version_number(paths):
    """The Python package's version comes from one place and equals the C library's."""
    import importlib.metadata
    r = subprocess.run([str(CLI), "--version"], capture_output=True, text=True, timeout=10)
    assert r.stdout.split()[-1] == ntscontact.__version__ == importlib.metadata.version("ntscontact")
    assert "version =" not in (REPO / "clients/python/pyproject.toml").read_text().split("[tool.setuptools.dynamic]")[0]

"""Mesh files to scenes: `ntscontact.mesh` and `python -m ntscontact convert`, on two
triangle-mesh disks written by meshio (Gmsh MSH 4.1 and VTK) in the test."""
import json
import subprocess
import sys

import numpy as np
import pytest

meshio = pytest.importorskip("meshio")
ntscontact = pytest.importorskip("ntscontact")
from ntscontact import Client, InvalidScene, Scene  # noqa: E402
from ntscontact.mesh import (  # noqa: E402
    bodies_from_mesh,
    boundary_loops,
    loop_area,
    orient_ccw,
    scene_from_mesh,
)

N_THETA = 24
OPTIONS = dict(penalty=200.0, alpha=0.2, search_radius=0.15)


def disk_mesh(cx, cy, r=1.0, rings=3, n=N_THETA):
    """A disk: a centre node, `rings` rings of n nodes, triangles of both
    orientations (every other one clockwise). Returns points (m, 2), triangles,
    and the outer ring's node indices in counter-clockwise order."""
    pts = [[cx, cy]]
    for k in range(1, rings + 1):
        t = 2 * np.pi * (np.arange(n) + 0.5 * (k % 2)) / n
        pts.extend(np.stack([cx + r * k / rings * np.cos(t), cy + r * k / rings * np.sin(t)], axis=1).tolist())
    ring = lambda k, i: 1 + (k - 1) * n + (i % n)  # noqa: E731
    tris = [[0, ring(1, i), ring(1, i + 1)] for i in range(n)]
    for k in range(1, rings):
        for i in range(n):
            a, b = ring(k, i), ring(k, i + 1)
            if k % 2:  # ring k is offset by half a step from ring k + 1
                c, d = ring(k + 1, i + 1), ring(k + 1, i)
            else:
                c, d = ring(k + 1, i), ring(k + 1, i - 1)
            tris += [[a, b, c], [a, c, d]]
    tris = np.array(tris)
    tris[1::2] = tris[1::2, ::-1]  # clockwise: the converter must orient them
    outer = np.array([ring(rings, i) for i in range(n)])
    return np.array(pts), tris, outer


@pytest.fixture(scope="module")
def two_disks():
    """Points (with a z column, shuffled), triangles per disk, outer rings per disk."""
    rng = np.random.default_rng(3)
    p1, t1, o1 = disk_mesh(0.0, 0.0)
    p2, t2, o2 = disk_mesh(1.93, 0.07)
    pts = np.vstack([p1, p2])
    t2, o2 = t2 + len(p1), o2 + len(p1)
    perm = rng.permutation(len(pts))  # new index of each old point
    inv = np.empty_like(perm)
    inv[perm] = np.arange(len(pts))
    pts = pts[inv]
    pts3 = np.column_stack([pts, np.full(len(pts), 0.25)])  # z is dropped
    return dict(points=pts3, tris=[perm[t1], perm[t2]], outer=[perm[o1], perm[o2]])


def original_index(d, nodes):
    """The written mesh's point index of each node, found by its coordinates (a
    reader may renumber points: meshio's MSH 4.1 groups them by entity)."""
    where = {tuple(p): i for i, p in enumerate(d["points"][:, :2].tolist())}
    return np.array([where[tuple(x)] for x in np.asarray(nodes).tolist()])


def write_msh(path, d):
    n = len(d["points"])
    dim_tags = np.zeros((n, 2), dtype=int)
    for k, t in enumerate(d["tris"]):
        dim_tags[np.unique(t)] = [2, k + 1]
    mesh = meshio.Mesh(
        d["points"], [("triangle", d["tris"][0]), ("triangle", d["tris"][1])],
        point_data={"gmsh:dim_tags": dim_tags},
        cell_data={"gmsh:physical": [np.full(len(t), 10 + k) for k, t in enumerate(d["tris"])],
                   "gmsh:geometrical": [np.full(len(t), k + 1) for k, t in enumerate(d["tris"])]},
        field_data={"left": np.array([10, 2]), "right": np.array([11, 2])})
    meshio.write(str(path), mesh, file_format="gmsh", binary=False)
    assert path.read_text().startswith("$MeshFormat\n4.1 ")


def write_vtk(path, d, tags=False):
    tris = np.vstack(d["tris"])
    cell_data = {}
    if tags:
        cell_data = {"body": [np.concatenate([np.full(len(t), k + 1) for k, t in enumerate(d["tris"])])]}
    meshio.write(str(path), meshio.Mesh(d["points"], [("triangle", tris)], cell_data=cell_data))


def hand_built(d):
    """The same two bodies given as their outer loops only, counter-clockwise."""
    s = Scene(**OPTIONS)
    for k, outer in enumerate(d["outer"]):
        s.add_body(d["points"][outer, :2], id=f"hand{k}")
    return s


@pytest.fixture(params=["msh41", "vtk", "vtk-tags"])
def mesh_file(request, tmp_path, two_disks):
    if request.param == "msh41":
        path = tmp_path / "disks.msh"
        write_msh(path, two_disks)
        return path, ["left", "right"]
    path = tmp_path / "disks.vtk"
    write_vtk(path, two_disks, tags=request.param == "vtk-tags")
    return path, [1, 2] if request.param == "vtk-tags" else [0, 1]


def test_two_disks_become_two_ccw_bodies(mesh_file, two_disks):
    path, ids = mesh_file
    bodies = bodies_from_mesh(path)
    assert [b.id for b in bodies] == ids
    for b, tris, outer in zip(bodies, two_disks["tris"], two_disks["outer"]):
        assert b.nodes.shape == (len(np.unique(tris)), 2) and b.nodes.dtype == np.float64
        orig = original_index(two_disks, b.nodes)  # z dropped, x and y bitwise kept
        assert sorted(orig.tolist()) == np.unique(tris).tolist()
        p = b.nodes[b.triangles]
        cross = ((p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1])
                 - (p[:, 1, 1] - p[:, 0, 1]) * (p[:, 2, 0] - p[:, 0, 0]))
        assert np.all(cross > 0), "every triangle counter-clockwise"
        loops = b.loops()
        assert len(loops) == 1
        assert loop_area(b.nodes, loops[0]) > 0, "the boundary is counter-clockwise"
        assert sorted(orig[loops[0]].tolist()) == sorted(outer.tolist())
        # the loop visits the outer ring in its counter-clockwise order (up to the start)
        ring = orig[loops[0]].tolist()
        start = ring.index(int(outer[0]))
        assert ring[start:] + ring[:start] == outer.tolist()


def test_forces_match_hand_built_scene(daemon, mesh_file, two_disks):
    path, ids = mesh_file
    with Client(daemon.base, timeout=30) as c:
        ref = c.contact(hand_built(two_disks), outputs=["forces", "energy", "contacts"])
        assert ref.summary.contacts > 0
        for boundary in ("triangles", "loops"):
            scene = scene_from_mesh(path, boundary=boundary, outputs=["forces", "energy", "contacts"], **OPTIONS)
            res = c.contact(scene)
            assert res.summary.contacts == ref.summary.contacts
            assert res.energy == pytest.approx(ref.energy, rel=1e-12)
            fmax = max(np.abs(f).max() for f in ref.forces.values())
            for k, b in enumerate(scene):
                f = res.forces[b.id]
                assert f.shape == b.nodes.shape
                want = dict(zip(two_disks["outer"][k].tolist(), ref.forces[f"hand{k}"]))
                got = dict(zip(original_index(two_disks, b.nodes).tolist(), f))
                interior = [i for i in got if i not in want]
                if boundary == "triangles":
                    assert interior and all(np.all(got[i] == 0.0) for i in interior)
                else:
                    assert not interior and len(got) == len(want)
                for i, fw in want.items():
                    np.testing.assert_allclose(got[i], fw, rtol=1e-10, atol=1e-12 * fmax)


def test_convert_command_and_c_cli(daemon, paths, tmp_path, two_disks):
    msh = tmp_path / "disks.msh"
    write_msh(msh, two_disks)
    out = tmp_path / "scene.json"
    proc = subprocess.run([sys.executable, "-m", "ntscontact", "convert", str(msh), "-o", str(out),
                           "--penalty", "200", "--alpha", "0.2", "--search-radius", "0.15",
                           "--outputs", "forces,energy,contacts"], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert "2 bodies" in proc.stderr
    doc = json.loads(out.read_text())
    assert [b["id"] for b in doc["bodies"]] == ["left", "right"]
    assert all(len(n) == 2 for b in doc["bodies"] for n in b["nodes"])
    cli = subprocess.run([str(paths.cli), str(out)], capture_output=True, timeout=120)
    assert cli.returncode == 0, cli.stderr
    cli_doc = json.loads(cli.stdout)
    with Client(daemon.base, timeout=30) as c:
        ref = c.contact(hand_built(two_disks), outputs=["forces", "energy", "contacts"])
        via_service = c.contact(Scene.load(out))
    assert cli_doc["summary"]["contacts"] == ref.summary.contacts > 0
    assert cli_doc["summary"]["energy"] == pytest.approx(ref.energy, rel=1e-12)
    cli_doc["summary"].pop("elapsed_ms")
    service = json.loads(json.dumps(via_service.raw))
    service["summary"].pop("elapsed_ms")
    assert service == cli_doc


def test_convert_usage_errors(tmp_path):
    bad = tmp_path / "bad.vtk"
    pts = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0.0]])
    meshio.write(str(bad), meshio.Mesh(pts, [("triangle", np.array([[0, 1, 2]]))]))
    proc = subprocess.run([sys.executable, "-m", "ntscontact", "convert", str(bad), "--penalty", "1"],
                          capture_output=True, text=True, timeout=120)
    # (a triangle of zero area is no fault of the mesh: its boundary encloses none)
    assert proc.returncode == 3 and "zero_area_loop" in proc.stderr
    proc = subprocess.run([sys.executable, "-m", "ntscontact", "convert"], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2


def test_orientation_and_boundary_helpers():
    pts = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 0.5]], dtype=float)
    cw = np.array([[0, 4, 1], [1, 4, 2], [2, 4, 3], [3, 4, 0]])  # all clockwise
    ccw = orient_ccw(pts, cw)
    (loop,) = boundary_loops(ccw)
    assert loop.tolist() == [0, 1, 2, 3] and loop_area(pts, loop) == 1.0
    with pytest.raises(InvalidScene) as ei:  # as the core: only its boundary's area matters
        orient_ccw(np.array([[0, 0], [1, 0], [2, 0]]), [[0, 1, 2]])
    assert ei.value.code == "zero_area_loop"
    with pytest.raises(InvalidScene) as ei:
        orient_ccw(np.array([[0, 0], [1, 0], [2, 0]]), [[0, 1, 1]])
    assert ei.value.code == "degenerate_triangle"
    # an interior triangle turned over: the same boundary, counter-clockwise
    flipped = cw.copy()
    flipped[1] = flipped[1][::-1]
    (loop,) = boundary_loops(orient_ccw(pts, flipped))
    assert loop.tolist() == [0, 1, 2, 3]
    fin = np.array([[0, 1, 2], [0, 1, 3], [1, 0, 4]])
    with pytest.raises(InvalidScene) as ei:
        boundary_loops(fin)
    assert ei.value.code == "non_manifold_mesh"
    # an annulus: the hole comes out clockwise
    outer = [[np.cos(a), np.sin(a)] for a in np.linspace(0, 2 * np.pi, 9)[:-1]]
    inner = [[0.5 * np.cos(a), 0.5 * np.sin(a)] for a in np.linspace(0, 2 * np.pi, 9)[:-1]]
    p = np.array(outer + inner)
    tris = [[i, (i + 1) % 8, 8 + i] for i in range(8)] + [[(i + 1) % 8, 8 + (i + 1) % 8, 8 + i] for i in range(8)]
    loops = boundary_loops(orient_ccw(p, tris))
    areas = sorted(loop_area(p, lp) for lp in loops)
    assert len(loops) == 2 and areas[0] < 0 < areas[1]


def test_components_without_tags_and_mesh_object(two_disks):
    tris = np.vstack(two_disks["tris"])
    mesh = meshio.Mesh(two_disks["points"], [("triangle", tris)])
    scene = scene_from_mesh(mesh, penalty=5.0)
    assert scene.body_ids == [0, 1] and scene.penalty == 5.0
    assert all(b.triangles is not None for b in scene)
    assert sum(b.node_count for b in scene) == len(two_disks["points"])


def test_disk_mesh():
    """The examples' and benchmarks' disk: 1 + 3 r (r + 1) nodes, 6 r^2
    counter-clockwise triangles covering the 6 r-gon, one boundary loop."""
    from ntscontact.mesh import boundary_loops, disk_mesh, loop_area
    for rings in (1, 2, 5):
        pts, tris = disk_mesh(2.0, rings, 1.0, -3.0)
        assert pts.shape == (1 + 3 * rings * (rings + 1), 2) and tris.shape == (6 * rings * rings, 3)
        a, b, c = pts[tris[:, 0]], pts[tris[:, 1]], pts[tris[:, 2]]
        areas = 0.5 * ((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]))
        assert (areas > 0).all()
        loops = boundary_loops(tris)
        assert len(loops) == 1 and len(loops[0]) == 6 * rings
        assert abs(areas.sum() - loop_area(pts, loops[0])) < 1e-12 * areas.sum()
        if rings == 1:  # the regular hexagon of radius 2
            assert abs(areas.sum() - 1.5 * 3 ** 0.5 * 4.0) < 1e-12
    with pytest.raises(ValueError):
        disk_mesh(1.0, 0)

"""Contact surfaces (a body's "surface", docs/model.md §13) in the Python
client: Scene(add_body(surface=...)) round trips and refuses what the service
refuses with the same code and JSON pointer (the CLI and the daemon asked the
same question), a session with surfaces answers as the one-shot call, the VTK
cell field, and `python -m ntscontact convert --surface NAME` from gmsh
physical curves (MSH 2.2 written by meshio, MSH 4.1 written here), evaluated by
the C CLI: the FEM user's two-block journey."""
import json
import pathlib
import subprocess
import sys

import jsonschema
import numpy as np
import pytest
import requests

from conftest import CLI, run_cli_json

ntscontact = pytest.importorskip("ntscontact")
meshio = pytest.importorskip("meshio")
from ntscontact import Client, InvalidScene, Scene  # noqa: E402
from ntscontact.mesh import scene_from_mesh, surfaces_from_mesh, bodies_from_mesh  # noqa: E402

SQUARE = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]


def stacked_scene(surfaces=True, overlap=0.01, reference=False):
    """Two unit squares given as one loop each, the upper one `overlap` into
    the lower one, non-matching (4 and 5 segments along the interface: lower
    nodes 3..7, upper nodes 0..5); with `surfaces`, each one's contact surface
    is its side on the interface. `reference`: the nodes as given are each
    body's reference configuration (the tributary lengths stay when it moves)."""
    lower = [[0.0, 0.0], [1.0, 0.0], [1.0, 0.5]] + [[x, 1.0] for x in np.linspace(1, 0, 5)] + [[0.0, 0.5]]
    upper = [[x, 1.0 - overlap] for x in np.linspace(0, 1, 6)] + [[1.0, 2.0 - overlap], [0.0, 2.0 - overlap]]
    s = Scene(penalty=1000.0, alpha=0.2, penalty_scaling="length", outputs=["forces", "pressure", "contacts"])
    s.add_body(lower, id="lower", surface=[[3, 4], [5, 4], [5, 6], [6, 7]] if surfaces else None,
               reference=lower if reference else None)
    s.add_body(upper, id="upper", surface=[[k, k + 1] for k in range(5)] if surfaces else None,
               reference=upper if reference else None)
    return s


# ------------------------------------------------------------ the Scene


def test_scene_round_trip_keeps_surfaces(schemas):
    pts, tri = ntscontact.mesh.disk_mesh(0.3, 2, 2.5, 0.5)
    s = stacked_scene()
    s.add_body(pts, triangles=tri, id="disk", surface=np.array([[7, 8], [9, 8]], dtype=np.int32))
    s.add_body(np.array(SQUARE) + [5.0, 0.0], id="off", surface=[])
    s.add_body(np.array(SQUARE) + [7.0, 0.0], id="plain")
    body = s.body("lower")
    assert body.surface.dtype == np.int64 and body.surface.shape == (4, 2)
    assert s.body("off").surface.shape == (0, 2) and s.body("plain").surface is None
    doc = s.to_dict()
    assert doc["bodies"][0]["surface"] == [[3, 4], [5, 4], [5, 6], [6, 7]]
    assert doc["bodies"][2]["surface"] == [[7, 8], [9, 8]]
    assert doc["bodies"][3]["surface"] == [] and "surface" not in doc["bodies"][4]
    again = Scene.from_json(s.to_json())
    assert again.to_dict() == doc
    for a, b in zip(again, s):
        assert (a.surface is None) == (b.surface is None)
        if a.surface is not None:
            assert np.array_equal(a.surface, b.surface) and a.surface.dtype == np.int64
    # the contract's and the service's (and a scene without surfaces reads and writes as before)
    jsonschema.validate(doc, schemas["scene"])
    assert run_cli_json(doc)["summary"]["bodies"] == 5
    plain = Scene(penalty=1.0)
    plain.add_body(SQUARE)
    assert plain.to_dict()["bodies"] == [{"id": 0, "nodes": SQUARE}]


def test_surfaces_take_effect():
    """The flush stack: with surfaces every interface node, corners included,
    carries the pressure penalty * overlap; without, the corners carry none."""
    for surfaces in (True, False):
        doc = stacked_scene(surfaces).to_dict()
        res = run_cli_json(doc)
        p = {b["id"]: np.array(b["pressure"]) for b in res["bodies"]}
        want = 1000.0 * (1.0 - (1.0 - 0.01))
        upper = p["upper"][:6]
        if surfaces:
            np.testing.assert_allclose(upper, want, rtol=1e-9)
            np.testing.assert_allclose(p["lower"][3:8], want, rtol=1e-9)
            assert not p["upper"][6:].any() and not p["lower"][[0, 1, 2, 8]].any()
        else:
            assert upper[0] == upper[5] == 0.0
            np.testing.assert_allclose(upper[1:5], want, rtol=1e-9)


# The same bad surface sent three ways: the client's own check, the CLI, the
# daemon. (body index, surface, code, pointer); body 0 is a loop body of 4
# nodes, body 1 one of 8 nodes with no loops given (one loop, all nodes).
BAD = [
    (0, [[0, 2]], "invalid_surface", "/bodies/0/surface/0"),
    (0, [[0, 1], [2, 3], [1, 0]], "invalid_surface", "/bodies/0/surface/2"),
    (0, [[1, 1]], "invalid_surface", "/bodies/0/surface/0"),
    (0, [[0, 1], [1, 3], [1, 3]], "invalid_surface", "/bodies/0/surface/1"),  # not a segment before the repeat
    (0, [[0, 4]], "index_out_of_range", "/bodies/0/surface/0/1"),
    (0, [[-1, 0]], "index_out_of_range", "/bodies/0/surface/0/0"),
    (0, [[0, 1], [1, 1e300]], "index_out_of_range", "/bodies/0/surface/1/1"),
    (0, [[0, 1.5]], "invalid_value", "/bodies/0/surface/0/1"),
    (0, [[0, "1"]], "invalid_type", "/bodies/0/surface/0/1"),
    (0, [[0, True]], "invalid_type", "/bodies/0/surface/0/1"),
    (0, [[0, None]], "invalid_type", "/bodies/0/surface/0/1"),
    (0, [[0]], "invalid_value", "/bodies/0/surface/0"),
    (0, [[0, 1, 2]], "invalid_value", "/bodies/0/surface/0/2"),
    (0, [[0, 1], 2], "invalid_type", "/bodies/0/surface/1"),
    (0, [[0, 1], {"i": 0}], "invalid_type", "/bodies/0/surface/1"),
    (0, "0 1", "invalid_type", "/bodies/0/surface"),
    (0, {"0": 1}, "invalid_type", "/bodies/0/surface"),
    (0, [[0, 1]] * 5, "invalid_value", "/bodies/0/surface"),
    (1, [[7, 0], [3, 4], [2, 4]], "invalid_surface", "/bodies/1/surface/2"),
    (1, [[0, 8]], "index_out_of_range", "/bodies/1/surface/0/1"),
    (2, [[0, 1], [4, 5], [5, 6], [6, 4], [3, 0]], "invalid_surface", "/bodies/2/surface/3"),  # across the hole
]


def bad_doc(body, surface):
    """A scene of three bodies: a square (loops), an octagon (no loops), a
    square with a square hole (two loops); `surface` on body `body`."""
    ring = [[np.cos(a), np.sin(a)] for a in 2 * np.pi * np.arange(8) / 8]
    frame = SQUARE + [[0.25, 0.25], [0.25, 0.75], [0.75, 0.75], [0.75, 0.25]]
    doc = {"version": 1, "options": {"penalty": 100.0},
           "bodies": [{"id": "sq", "nodes": SQUARE, "loops": [[0, 1, 2, 3]]},
                      {"id": "oct", "nodes": (np.array(ring) + [3.0, 0.0]).tolist()},
                      {"id": "frame", "nodes": (np.array(frame) + [6.0, 0.0]).tolist(),
                       "loops": [[0, 1, 2, 3], [4, 5, 6, 7]]}]}
    doc["bodies"][body]["surface"] = surface
    return doc


def cli_fault(doc):
    r = subprocess.run([str(CLI), "-"], input=json.dumps(doc).encode(), capture_output=True, timeout=60)
    assert r.returncode == 3, (r.returncode, r.stderr)
    line = r.stderr.decode().strip().splitlines()[-1]
    head = line.split(": ", 1)[1]  # ntscontact: CODE at "POINTER": message
    code, rest = head.split(" at ", 1)
    return code, rest.split('"')[1]


@pytest.mark.parametrize("body,surface,code,pointer", BAD, ids=[f"{c}-{i}" for i, (_, _, c, _) in enumerate(BAD)])
def test_client_refuses_as_the_service_does(daemon, body, surface, code, pointer):
    doc = bad_doc(body, surface)
    with pytest.raises(InvalidScene) as ei:
        Scene.from_dict(doc)
    assert (ei.value.code, ei.value.pointer, ei.value.status) == (code, pointer, None), str(ei.value)
    pair = f"surface pair {pointer.split('/')[4]}" if pointer.count("/") > 3 else "surface"
    assert pair in str(ei.value)
    assert cli_fault(doc) == (code, pointer)
    r = requests.post(daemon.url("/v1/contact"), json=doc, timeout=30)
    assert r.status_code == 400
    err = r.json()["error"]
    assert (err["code"], err["pointer"]) == (code, pointer)
    # the client sends a dict as it is: the service's error comes back typed, naming the pair
    with Client(daemon.base, timeout=30) as c:
        with pytest.raises(InvalidScene) as ei:
            c.contact(doc)
    assert (ei.value.code, ei.value.pointer, ei.value.status) == (code, pointer, 400)
    assert pair in str(ei.value)


def test_numpy_surfaces_are_checked_alike():
    s = Scene(penalty=1.0)
    s.add_body(SQUARE, surface=np.array([[0, 1], [3, 2]], dtype=np.uint8))
    s.add_body(SQUARE, surface=np.array([[0.0, 1.0]]))
    assert s.to_dict()["bodies"][1]["surface"] == [[0, 1]]
    for surface, code, pointer in ((np.array([[0, 5]]), "index_out_of_range", "/bodies/2/surface/0/1"),
                                   (np.array([[0.0, 0.5]]), "invalid_value", "/bodies/2/surface/0/1"),
                                   (np.array([[0, 1, 2]]), "invalid_value", "/bodies/2/surface/0/2"),
                                   (np.array([0, 1]), "invalid_type", "/bodies/2/surface/0"),
                                   (np.array([[0, 2]]), "invalid_surface", "/bodies/2/surface/0"),
                                   (np.zeros((5, 2), dtype=int), "invalid_value", "/bodies/2/surface")):
        with pytest.raises(InvalidScene) as ei:
            s.add_body(SQUARE, surface=surface)
        assert (ei.value.code, ei.value.pointer) == (code, pointer)
    assert len(s) == 2  # a refused body is not added


def test_triangle_bodies_are_checked_by_the_service(daemon):
    """Which pairs bound a triangle mesh is the service's to say: the client
    sends them, the service refuses an interior edge or a repeat."""
    pts, tri = ntscontact.mesh.disk_mesh(1.0, 2)
    for surface, k in (([[7, 8], [0, 1]], 1), ([[7, 8], [8, 9], [8, 7]], 2)):
        s = Scene(penalty=10.0)
        s.add_body(pts, triangles=tri, surface=surface)
        with Client(daemon.base, timeout=30) as c:
            with pytest.raises(InvalidScene) as ei:
                c.contact(s)
        assert (ei.value.code, ei.value.pointer, ei.value.status) == ("invalid_surface", f"/bodies/0/surface/{k}", 400)
        assert cli_fault(s.to_dict()) == ("invalid_surface", f"/bodies/0/surface/{k}")
        with Client(daemon.base, timeout=30) as c:  # a session is refused alike (POST /v1/scenes)
            with pytest.raises(InvalidScene) as ei:
                c.session(s)
        assert (ei.value.code, ei.value.pointer, ei.value.status) == ("invalid_surface", f"/bodies/0/surface/{k}", 400)


# ------------------------------------------------------------ over HTTP


def test_session_with_surfaces_answers_as_the_one_shot_call(daemon):
    scene = stacked_scene(reference=True)  # what a session keeps: the lengths of its first positions
    rng = np.random.default_rng(25)
    with Client(daemon.base, timeout=60) as c:
        with c.session(scene) as s:
            x0 = s.positions()
            for step in range(3):
                x = x0 + rng.uniform(-2e-3, 2e-3, size=x0.shape)
                got = s.contact(x)
                scene.set_positions(x)
                want = c.contact(scene)
                assert got.summary.contacts == want.summary.contacts > 0
                assert np.array_equal(got.force_array(), want.force_array())
                assert np.array_equal(got.pressure_array(), want.pressure_array())
                assert [(k.slave_body, k.slave_node, k.gap) for k in got.contacts] == \
                       [(k.slave_body, k.slave_node, k.gap) for k in want.contacts]
        # no contact ever involves a node off the surface
        on = {("lower", i) for i in range(3, 8)} | {("upper", i) for i in range(6)}
        assert {(k.slave_body, k.slave_node) for k in want.contacts} <= on


# ------------------------------------------------------------ VTK


def test_vtk_surface_field(daemon, tmp_path):
    scene = stacked_scene()
    scene.add_body(np.array(SQUARE) + [3.0, 0.0], id="off", surface=[])
    with Client(daemon.base, timeout=60) as c:
        res = c.contact(scene)
    res.to_vtk(tmp_path / "s.vtu")
    m = meshio.read(tmp_path / "s.vtu")
    kind, surf = np.concatenate(m.cell_data["kind"]), np.concatenate(m.cell_data["surface"])
    lines = np.concatenate([b.data for b in m.cells])
    assert (surf[kind == 1] == -1).all() and (kind == 1).sum() == len(res.contacts) > 0
    on = {tuple(sorted(map(int, ln))) for ln, k, f in zip(lines, kind, surf) if k == 0 and f == 1}
    off = {tuple(sorted(map(int, ln))) for ln, k, f in zip(lines, kind, surf) if k == 0 and f == 0}
    named = {tuple(sorted((o + int(a), o + int(b)))) for o, body in zip((0, 9), scene) for a, b in body.surface}
    assert on == named and len(off) == (9 + 8 + 4) - len(named)  # every segment of "off" too


# ------------------------------------------------------------ convert --surface


def block(x0, y0, w, h, nx, ny, base):
    """Structured triangles on [x0, x0 + w] x [y0, y0 + h]: points (with z),
    triangles, and the bottom and top rows of line elements (left to right,
    right to left: the boundary's direction does not matter)."""
    xs, ys = np.linspace(x0, x0 + w, nx + 1), np.linspace(y0, y0 + h, ny + 1)
    pts = np.array([[x, y, 0.0] for y in ys for x in xs])

    def v(i, j):
        return base + j * (nx + 1) + i

    tris = [t for j in range(ny) for i in range(nx)
            for t in ([v(i, j), v(i + 1, j), v(i + 1, j + 1)], [v(i, j), v(i + 1, j + 1), v(i, j + 1)])]
    bottom = [[v(i, 0), v(i + 1, 0)] for i in range(nx)]
    top = [[v(i + 1, ny), v(i, ny)] for i in range(nx)]
    return pts, np.array(tris), np.array(bottom), np.array(top)


OVERLAP = 0.01
PENALTY = 1000.0
#: The two-block model's physical groups: name -> (tag, dim).
GROUPS = {"lower": (1, 2), "upper": (2, 2), "contact_lower": (3, 1), "contact_upper": (4, 1), "fixed": (5, 1),
          "mid": (6, 1)}


def two_blocks(overlap=OVERLAP):
    """An FEM user's model: physical surfaces "lower" ([0, 1]^2, 4 x 2 squares)
    and "upper" (on top, `overlap` into it, 5 x 2: non-matching), physical
    curves "contact_lower" (the lower block's top), "contact_upper" (the upper
    block's bottom), "fixed" (the lower block's bottom, a boundary condition's
    curve) and "mid" (a line through the lower block, on no boundary).
    Returns points and blocks (gmsh dim, entity, physical tags, cell type,
    connectivity)."""
    pl, tl, bl, topl = block(0.0, 0.0, 1.0, 1.0, 4, 2, 0)
    pu, tu, bu, _ = block(0.0, 1.0 - overlap, 1.0, 1.0, 5, 2, len(pl))
    blocks = [(2, 1, [1], "triangle", tl), (2, 2, [2], "triangle", tu), (1, 1, [3], "line", topl),
              (1, 2, [4], "line", bu), (1, 3, [5], "line", bl), (1, 4, [6], "line", np.array([[5, 6]]))]
    return np.vstack([pl, pu]), blocks


def write_gmsh22(path, points, blocks, groups=GROUPS):
    """MSH 2.2 ASCII through meshio."""
    cells = [(kind, conn) for _, _, _, kind, conn in blocks]
    mesh = meshio.Mesh(points, cells,
                       cell_data={"gmsh:physical": [np.full(len(b[4]), b[2][0]) for b in blocks],
                                  "gmsh:geometrical": [np.full(len(b[4]), b[1]) for b in blocks]},
                       field_data={name: np.array(td) for name, td in groups.items()})
    meshio.write(str(path), mesh, file_format="gmsh22", binary=False)
    assert path.read_text().startswith("$MeshFormat\n2.2 ")


def write_msh41(path, points, blocks, groups=GROUPS):
    """MSH 4.1 ASCII as gmsh writes it: physical names, entities with their
    physical tags (an entity may be in several groups), nodes, elements."""
    gmsh_type = {"line": 1, "triangle": 2}
    entities = {}
    for dim, ent, phys, _, _ in blocks:
        entities.setdefault((dim, ent), []).extend(phys)
    out = ["$MeshFormat", "4.1 0 8", "$EndMeshFormat", "$PhysicalNames", str(len(groups))]
    out += [f'{d} {t} "{name}"' for name, (t, d) in groups.items()]
    curves = sorted(e for d, e in entities if d == 1)
    surfaces = sorted(e for d, e in entities if d == 2)
    out += ["$EndPhysicalNames", "$Entities", f"0 {len(curves)} {len(surfaces)} 0"]
    for dim, tags in ((1, curves), (2, surfaces)):
        for e in tags:
            phys = sorted(set(entities[(dim, e)]))
            out.append(f"{e} 0 0 0 1 1 0 {len(phys)} {' '.join(map(str, phys))} 0")
    n = len(points)
    out += ["$EndEntities", "$Nodes", f"1 {n} 1 {n}", f"2 {surfaces[0]} 0 {n}"]
    out += [str(i + 1) for i in range(n)] + [f"{x!r} {y!r} 0" for x, y in np.asarray(points)[:, :2].tolist()]
    total = sum(len(b[4]) for b in blocks)
    out += ["$EndNodes", "$Elements", f"{len(blocks)} {total} 1 {total}"]
    k = 1
    for dim, ent, _, kind, conn in blocks:
        out.append(f"{dim} {ent} {gmsh_type[kind]} {len(conn)}")
        for row in np.asarray(conn).tolist():
            out.append(" ".join(map(str, [k] + [v + 1 for v in row])))
            k += 1
    path.write_text("\n".join(out + ["$EndElements", ""]))


def convert(path, *flags):
    out = pathlib.Path(path).with_suffix(".json")
    r = subprocess.run([sys.executable, "-m", "ntscontact", "convert", str(path), "-o", str(out), "--penalty",
                        str(PENALTY), "--penalty-scaling", "length", "--outputs", "forces,pressure,contacts", *flags],
                       capture_output=True, text=True, timeout=120)
    return r, (json.loads(out.read_text()) if r.returncode == 0 else None)


def interface(doc, body):
    """The node indices of a body of a converted scene on the interface (y = 1 - overlap or y = 1)."""
    y = 1.0 if body["id"] == "lower" else 1.0 - OVERLAP
    return {i for i, (_, yi) in enumerate(body["nodes"]) if yi == y}


@pytest.fixture(params=["msh22", "msh41"])
def model(request, tmp_path):
    points, blocks = two_blocks()
    path = tmp_path / "blocks.msh"
    (write_gmsh22 if request.param == "msh22" else write_msh41)(path, points, blocks)
    return path


@pytest.mark.parametrize("loops", [False, True], ids=["triangles", "loops"])
def test_convert_surface_journey(model, loops):
    """convert --surface contact_upper --surface contact_lower, then the C
    CLI: only the interface's segments are on the surfaces, and every
    interface node of both blocks, corners included, carries the pressure
    penalty * overlap; nothing else does."""
    r, doc = convert(model, "--surface", "contact_upper", "--surface", "contact_lower", *(["--loops"] if loops else []))
    assert r.returncode == 0, r.stderr
    assert "contact surfaces: 'lower' 4 segments, 'upper' 5 segments" in r.stderr
    assert [b["id"] for b in doc["bodies"]] == ["lower", "upper"]
    for body in doc["bodies"]:
        iface = interface(doc, body)
        assert len(iface) == (5 if body["id"] == "lower" else 6)
        assert {i for pair in body["surface"] for i in pair} == iface
        assert len(body["surface"]) == len(iface) - 1
        assert ("loops" in body) == loops and ("triangles" in body) != loops
    res = run_cli_json(doc)
    want = PENALTY * (1.0 - (1.0 - OVERLAP))
    for body, rb in zip(doc["bodies"], res["bodies"]):
        p = np.array(rb["pressure"])
        iface = sorted(interface(doc, body))
        np.testing.assert_allclose(p[iface], want, rtol=1e-9)
        assert not np.delete(p, iface).any()
    # The Python function gives the same scene.
    scene = scene_from_mesh(model, penalty=PENALTY, penalty_scaling="length",
                            outputs=["forces", "pressure", "contacts"], surfaces=["contact_upper", "contact_lower"],
                            boundary="loops" if loops else "triangles")
    assert scene.to_dict() == doc


def test_convert_without_surfaces_leaves_the_corners_out(model):
    r, doc = convert(model)
    assert r.returncode == 0, r.stderr
    assert all("surface" not in b for b in doc["bodies"])
    res = run_cli_json(doc)
    want = PENALTY * (1.0 - (1.0 - OVERLAP))
    for body, rb in zip(doc["bodies"], res["bodies"]):
        p = np.array(rb["pressure"])
        xs = {i: body["nodes"][i][0] for i in interface(doc, body)}
        corners = [i for i, x in xs.items() if x in (0.0, 1.0)]
        inner = [i for i, x in xs.items() if x not in (0.0, 1.0)]
        assert len(corners) == 2 and not p[corners].any()
        np.testing.assert_allclose(p[inner], want, rtol=1e-9)


def test_convert_one_side_and_other_bodies(model):
    """Only the upper block's curve: the lower block keeps its whole boundary
    (the default), or has no surface with --other-bodies none."""
    r, doc = convert(model, "--surface", "contact_upper")
    assert r.returncode == 0, r.stderr
    assert "whole boundary: 'lower'" in r.stderr
    lower, upper = doc["bodies"]
    assert "surface" not in lower and len(upper["surface"]) == 5
    assert scene_from_mesh(model, penalty=PENALTY, penalty_scaling="length", outputs=["forces", "pressure", "contacts"],
                           surfaces="contact_upper").to_dict() == doc  # one name as a string
    # the upper block's corners still find the lower block's sides (its whole
    # boundary) at no distance: only the inner nodes press
    p = np.array(run_cli_json(doc)["bodies"][1]["pressure"])[sorted(interface(doc, upper))]
    assert p[0] == p[-1] == 0.0
    np.testing.assert_allclose(p[1:-1], PENALTY * (1.0 - (1.0 - OVERLAP)), rtol=1e-9)
    r, doc = convert(model, "--surface", "contact_upper", "--other-bodies", "none")
    assert r.returncode == 0, r.stderr
    assert "no surface: 'lower'" in r.stderr
    assert doc["bodies"][0]["surface"] == [] and len(doc["bodies"][1]["surface"]) == 5
    assert run_cli_json(doc)["summary"]["contacts"] == 0  # the lower block offers nothing, and is never a slave
    # a name twice, or a curve whose edges another name gives too: each edge once
    r, again = convert(model, "--surface", "contact_upper", "--surface", "contact_upper", "--other-bodies", "none")
    assert r.returncode == 0 and again == doc


def test_an_entity_in_two_groups(tmp_path):
    """MSH 4.1: the upper block's bottom is in "contact_upper" and in
    "contacts" (with the lower block's top): one name gives both surfaces, and
    the union with another name that overlaps it gives each edge once."""
    points, blocks = two_blocks()
    blocks[2] = blocks[2][:2] + ([3, 7],) + blocks[2][3:]
    blocks[3] = blocks[3][:2] + ([4, 7],) + blocks[3][3:]
    path = tmp_path / "m.msh"
    write_msh41(path, points, blocks, {**GROUPS, "contacts": (7, 1)})
    r, one = convert(path, "--surface", "contacts")
    assert r.returncode == 0, r.stderr
    r, both = convert(path, "--surface", "contacts", "--surface", "contact_lower", "--surface", "contact_upper")
    assert r.returncode == 0, r.stderr
    assert one == both and [len(b["surface"]) for b in one["bodies"]] == [4, 5]


def test_convert_surface_errors(model, tmp_path):
    for flags, words in ((["--surface", "nope"], ["'nope'", "'contact_lower', 'contact_upper', 'fixed', 'mid'"]),
                         (["--surface", "upper"], ["'upper' is 2D", "1D physical group"]),
                         (["--surface", "contact_upper", "--surface", "mid"],
                          ["'mid'", "line element 0", "mesh points 5", "not an edge of any body's boundary"])):
        r, _ = convert(model, *flags)
        assert r.returncode == 3, r.stderr
        assert r.stderr.startswith("ntscontact: invalid_surface: ") and "Traceback" not in r.stderr
        assert all(w in r.stderr for w in words), r.stderr
    r, _ = convert(model, "--other-bodies", "none")
    assert r.returncode == 2 and "--other-bodies needs --surface" in r.stderr
    # The Python function raises the typed error, and so does a mesh that names no groups.
    with pytest.raises(InvalidScene) as ei:
        scene_from_mesh(model, penalty=1.0, surfaces=["contact_upper", "nope"])
    assert ei.value.code == "invalid_surface" and "'nope'" in str(ei.value)
    with pytest.raises(ValueError, match="needs surfaces"):
        scene_from_mesh(model, penalty=1.0, other_bodies="none")
    points, blocks = two_blocks()
    vtk = tmp_path / "m.vtk"
    meshio.write(str(vtk), meshio.Mesh(points, [("triangle", np.vstack([blocks[0][4], blocks[1][4]]))]))
    r, _ = convert(vtk, "--surface", "contact_upper")
    assert r.returncode == 3 and "names no physical curve" in r.stderr, r.stderr


def test_a_line_two_bodies_share(tmp_path):
    """Blocks meshed together (the interface's points shared): a line on it is
    on both bodies' boundaries, which is refused, naming both."""
    pl, tl, _, topl = block(0.0, 0.0, 1.0, 1.0, 2, 1, 0)
    pu = np.array([[x, 2.0, 0.0] for x in (0.0, 0.5, 1.0)])
    tu = np.array([[3, 4, 7], [3, 7, 6], [4, 5, 8], [4, 8, 7]])
    points = np.vstack([pl, pu])
    blocks = [(2, 1, [1], "triangle", tl), (2, 2, [2], "triangle", tu), (1, 1, [3], "line", topl)]
    path = tmp_path / "shared.msh"
    write_gmsh22(path, points, blocks, {"lower": (1, 2), "upper": (2, 2), "contact_lower": (3, 1)})
    with pytest.raises(InvalidScene) as ei:
        surfaces_from_mesh(path, bodies_from_mesh(path), ["contact_lower"])
    assert ei.value.code == "invalid_surface"
    assert "bodies 'lower', 'upper'" in str(ei.value) and "share" in str(ei.value)


def test_plot_draws_the_surfaces_as_the_core_sees_them(tmp_path):
    """A body with a surface: its outline dotted, the surface solid with its
    inner corners smoothed and its ends sharp (at the end nodes themselves)."""
    matplotlib = pytest.importorskip("matplotlib")
    matplotlib.use("Agg")
    scene = stacked_scene()
    ax = ntscontact.plot(scene)
    styles = [(ln.get_linestyle(), len(ln.get_xydata())) for ln in ax.lines]
    # per body: the dotted outline, one solid piece, the node markers
    assert [s for s, _ in styles] == [":", "-", "None"] * 2
    lower, upper = ax.lines[1].get_xydata(), ax.lines[4].get_xydata()
    assert lower[0].tolist() == [1.0, 1.0] and lower[-1].tolist() == [0.0, 1.0]  # nodes 3 and 7
    assert upper[0].tolist() == [0.0, 0.99] and upper[-1].tolist() == [1.0, 0.99]  # nodes 0 and 5
    assert len(lower) == 2 + 3 * 8 and len(upper) == 2 + 4 * 8  # each inner corner sampled
    ax.figure.savefig(tmp_path / "p.png")


def test_surface_extension_is_an_option_of_the_scene():
    """Scene(surface_extension=...) is sent as options.surface_extension, read
    back by from_dict, and checked for its range as the core checks it."""
    scene = ntscontact.Scene(penalty=10.0, surface_extension=0.05)
    assert scene.options_dict()["surface_extension"] == 0.05
    back = ntscontact.Scene.from_dict(scene.to_dict())
    assert back.surface_extension == 0.05 and "surface_extension" not in back.extra_options
    with pytest.raises(ntscontact.InvalidScene) as e:
        ntscontact.Scene(penalty=10.0, surface_extension=0.6)
    assert e.value.pointer == "/options/surface_extension"

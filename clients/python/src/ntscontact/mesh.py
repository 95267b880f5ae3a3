"""Scenes from mesh files (any format meshio reads), ``pip install ntscontact[mesh]``.

Bodies come from cell tags when the mesh has them (``gmsh:physical``, or another
integer ``cell_data`` field), otherwise from the connected components of the
triangles. Coordinates keep x and y: a constant z is dropped, a z that varies
is a 3D mesh and refused; each connected piece is oriented as the core orients
it (through its shared edges, its outer loop counter-clockwise, holes
clockwise; a triangle turned over inside is no fault).

Contact surfaces (docs/model.md §13) come from gmsh physical curves: the line
elements of the named 1D physical groups, each an edge of one body's boundary
(:func:`surfaces_from_mesh`, ``scene_from_mesh(..., surfaces=[...])``).

Each body is checked by the core's own rule for a triangle mesh
(``core/src/triangles.c``, :func:`check_triangles`), so a mesh that converts is
one the core accepts as triangles, and one it would refuse is refused here
with the same code, naming the mesh point and the triangle.
"""

from __future__ import annotations

import contextlib
import io
import math
import os
import re
from dataclasses import dataclass
from typing import Any, Dict, List, Optional, Sequence, Set, Tuple, Union

import numpy as np
import numpy.typing as npt

from .errors import InvalidScene
from .scene import BodyId, Scene

__all__ = [
    "MeshBody",
    "check_triangles",
    "bodies_from_mesh",
    "surfaces_from_mesh",
    "scene_from_mesh",
    "orient_ccw",
    "boundary_loops",
    "connected_components",
    "loop_area",
    "disk_mesh",
]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

#: Cell types taken as (split into) linear triangles; higher-order cells keep their corners.
_TRIANGLE_CORNERS = {"triangle": 3, "triangle6": 3, "triangle7": 3}
_QUAD_CORNERS = {"quad": 4, "quad8": 4, "quad9": 4}
#: Line cells (``line``, ``line3``, ...): a higher-order line keeps its two end points.
_LINE = re.compile(r"^line\d*$")
#: Cell types of a 3D mesh (volumes): a mesh that has them is not ntscontact's.
_VOLUME_CELLS = ("tetra", "hexahedron", "wedge", "pyramid")
#: cell_data fields tried, in this order, when no tag is named.
_TAG_NAMES = ("gmsh:physical", "medit:ref", "CellEntityIds", "cell_tags", "tag", "tags", "body", "bodies",
              "region", "material", "gmsh:geometrical")


def disk_mesh(radius: float, rings: int, cx: float = 0.0, cy: float = 0.0) -> Tuple[FloatArray, IntArray]:
    """A disk of linear triangles for examples and benchmarks: a centre node and
    ``rings`` rings of 6k nodes (node 0 the centre; node 1 + 3 k (k - 1) starts
    ring k, at angle 0), triangles counter-clockwise. Returns (points, triangles)."""
    if rings < 1 or not radius > 0.0:
        raise ValueError("disk_mesh needs rings >= 1 and radius > 0")
    pts = [(cx, cy)]
    start = [0]
    for k in range(1, rings + 1):
        start.append(len(pts))
        for j in range(6 * k):
            a = 2 * math.pi * j / (6 * k)
            pts.append((cx + radius * k / rings * math.cos(a), cy + radius * k / rings * math.sin(a)))
    tris = []
    for k in range(1, rings + 1):
        n_in, n_out = 6 * (k - 1), 6 * k
        for j in range(n_out):
            o0, o1 = start[k] + j, start[k] + (j + 1) % n_out
            if k == 1:
                tris.append((0, o0, o1))
                continue
            # the inner node under this outer edge, and the next one
            ji = (j * n_in) // n_out
            i0 = start[k - 1] + ji % n_in
            tris.append((i0, o0, o1))
            if ((j + 1) * n_in) // n_out != ji or j == n_out - 1:
                tris.append((i0, o1, start[k - 1] + (ji + 1) % n_in))
    return np.array(pts, dtype=np.float64), np.array(tris, dtype=np.int64)


@dataclass
class MeshBody:
    """One body taken from a mesh: ``nodes`` (n, 2), counter-clockwise ``triangles``
    (m, 3) in local numbering, ``point_index`` (n,) the mesh's point of each node."""

    id: BodyId
    nodes: FloatArray
    triangles: IntArray
    point_index: IntArray

    def loops(self) -> List[IntArray]:
        """Boundary loops in local numbering (outer counter-clockwise, holes clockwise)."""
        return boundary_loops(self.triangles)


def check_triangles(
    nodes: npt.ArrayLike,
    triangles: npt.ArrayLike,
    *,
    point_index: Optional[npt.ArrayLike] = None,
    body: Optional[str] = None,
) -> None:
    """Refuse a body's triangle mesh exactly when the core would
    (``nts_boundary_from_triangles`` in ``core/src/triangles.c``), with the same
    code and the same triangle (``pointer`` ``/triangles/T``, relative to the
    body), in the same order of checks:

    1. triangle by triangle, a node index out of range (``index_out_of_range``)
       or a node repeated (``degenerate_triangle``);
    2. over the edges sorted by (smaller node, larger node, triangle): an edge
       of three or more triangles (``non_manifold_mesh``, at the third);
    3. piece by piece, from its first triangle: two triangles sharing an edge
       that cannot run it opposite ways (``non_manifold_mesh``: not orientable);
    4. triangle by triangle, a node that two boundary edges leave, a pinch
       point (``non_manifold_mesh``);
    5. no boundary edge at all (``no_boundary``).

    Only the connectivity counts, as in the core: a triangle of zero area or
    turned over is no fault. ``point_index`` (the mesh point of each node) and
    ``body`` only make the message name the mesh's points and the body.
    Raises :class:`InvalidScene`.
    """
    t = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    n = np.asarray(nodes, dtype=np.float64).reshape(-1, 2).shape[0]
    pidx = None if point_index is None else np.asarray(point_index, dtype=np.int64)
    prefix = f"body {body}: " if body is not None else ""

    def node_name(k: int) -> str:
        return f"mesh point {int(pidx[k])}" if pidx is not None else f"node {k}"

    def corners(k: int) -> str:
        return "(" + ", ".join(str(int(pidx[v])) if pidx is not None else str(int(v)) for v in t[k]) + ")"

    try:
        _mesh_rule(t, n)
    except _MeshFault as f:
        if f.code == "no_boundary":
            raise InvalidScene(prefix + f.what, code=f.code,
                               where=f"body {body}" if body is not None else "") from None
        if f.node is not None:  # a pinch point
            others = [k for k in range(f.tri) if f.node in t[k]]
            other = f" and {others[0]} {corners(others[0])}" if others else ""
            msg = (f"{node_name(f.node)} is a pinch point (two boundary edges leave it, one in triangle {f.tri}): "
                   f"triangles {f.tri} {corners(f.tri)}{other} meet there with no edge between them; the core "
                   "refuses such a body: give each side its own body (a cell tag) or its own copy of the point")
        elif f.code == "index_out_of_range":
            msg = f"triangle {f.tri}: {f.what}"
        else:
            msg = f"triangle {f.tri} {corners(f.tri)} {f.what}"
        pointer = f"/triangles/{f.tri}" + ("" if f.corner is None else f"/{f.corner}")
        raise InvalidScene(prefix + msg, code=f.code, pointer=pointer,
                           where=(f"body {body}, " if body is not None else "") + f"triangle {f.tri}") from None


def orient_ccw(points: npt.ArrayLike, triangles: npt.ArrayLike) -> IntArray:
    """A copy of ``triangles`` oriented as the core orients a mesh: each
    connected piece (triangles sharing edges) consistently, through its shared
    edges, and turned so that its outer loop (the boundary loop of largest
    |area|) runs counter-clockwise; an interior triangle turned over stays as
    its neighbours make it. A mesh the core refuses raises
    :class:`InvalidScene` (:func:`check_triangles`), and so does a piece whose
    boundary encloses no area (``zero_area_loop``)."""
    p = np.asarray(points, dtype=np.float64)[:, :2]
    t = np.array(triangles, dtype=np.int64, copy=True).reshape(-1, 3)
    check_triangles(p, t)
    flip, piece, _ = _mesh_rule(t, p.shape[0])
    t[flip, 1], t[flip, 2] = t[flip, 2].copy(), t[flip, 1].copy()
    for k in range(int(piece.max()) + 1 if piece.size else 0):
        mine = piece == k
        areas = [loop_area(p, lp) for lp in boundary_loops(t[mine])]
        outer = areas[int(np.argmax(np.abs(areas)))]
        first = int(np.flatnonzero(mine)[0])
        if outer == 0.0:
            raise InvalidScene(f"the piece of the mesh with triangle {first} encloses zero area",
                               code="zero_area_loop", where=f"triangle {first}")
        if outer < 0.0:
            sub = t[mine]
            sub[:, [1, 2]] = sub[:, [2, 1]]
            t[mine] = sub
    return t


class _MeshFault(Exception):
    """Where _mesh_rule stopped: the core's code, triangle, corner, what, node."""

    def __init__(self, code: str, tri: int, corner: Optional[int], what: str, node: Optional[int] = None):
        super().__init__(what)
        self.code, self.tri, self.corner, self.what, self.node = code, tri, corner, what, node


def _mesh_rule(t: IntArray, n: int) -> Tuple[npt.NDArray[np.bool_], IntArray, Dict[int, int]]:
    """The core's rule for a triangle mesh (``nts_boundary_from_triangles``),
    step for step: each triangle's indices in range and distinct; each edge in
    at most two triangles; each piece (through shared edges) oriented from its
    first triangle as given, two triangles sharing an edge running it
    opposite ways; the boundary (the edges of one triangle, in that
    orientation) with no node that two boundary edges leave; some boundary.
    Returns each triangle's flip, its piece and the boundary's next node;
    raises _MeshFault at the first fault, the one the core reports."""
    m = t.shape[0]
    for k in range(m):
        for c in range(3):
            if not 0 <= int(t[k, c]) < n:
                raise _MeshFault("index_out_of_range", k, c, f"node index {int(t[k, c])} is out of range [0, {n})")
        if t[k, 0] == t[k, 1] or t[k, 1] == t[k, 2] or t[k, 0] == t[k, 2]:
            raise _MeshFault("degenerate_triangle", k, None, "repeats a node: it has no edges of its own")
    frm = np.concatenate([t[:, 0], t[:, 1], t[:, 2]])
    to = np.concatenate([t[:, 1], t[:, 2], t[:, 0]])
    tri = np.concatenate([np.arange(m)] * 3)
    corner = np.repeat(np.arange(3), m)
    lo, hi = np.minimum(frm, to), np.maximum(frm, to)
    order = np.lexsort((tri, hi, lo))
    frm, tri, corner, lo, hi = frm[order], tri[order], corner[order], lo[order], hi[order]
    nb = np.full((m, 3), -1, dtype=np.int64)
    same = np.zeros((m, 3), dtype=bool)
    i, ne = 0, frm.size
    while i < ne:
        j = i
        while j < ne and lo[j] == lo[i] and hi[j] == hi[i]:
            j += 1
        if j - i > 2:
            raise _MeshFault("non_manifold_mesh", int(tri[i + 2]), None,
                             f"shares its edge ({int(lo[i])}, {int(hi[i])}) with {j - i - 1} other triangles "
                             f"({int(tri[i])}, {int(tri[i + 1])}, ...): at most two may share an edge")
        if j - i == 2:
            a, c = i, i + 1
            nb[tri[a], corner[a]] = tri[c]
            nb[tri[c], corner[c]] = tri[a]
            same[tri[a], corner[a]] = same[tri[c], corner[c]] = frm[a] == frm[c]
        i = j
    piece = np.full(m, -1, dtype=np.int64)
    flip = np.zeros(m, dtype=bool)
    pieces = 0
    for t0 in range(m):
        if piece[t0] != -1:
            continue
        piece[t0] = pieces
        queue = [t0]
        head = 0
        while head < len(queue):
            u = queue[head]
            head += 1
            for k in range(3):
                w = int(nb[u, k])
                if w < 0:
                    continue
                want = bool(flip[u] ^ same[u, k])
                if piece[w] == -1:
                    piece[w], flip[w] = pieces, want
                    queue.append(w)
                elif flip[w] != want:
                    a, c = int(t[u, k]), int(t[u, (k + 1) % 3])
                    raise _MeshFault("non_manifold_mesh", w, None,
                                     f"cannot be oriented as its neighbours are (across edge ({min(a, c)}, "
                                     f"{max(a, c)}) from triangle {u}): the mesh is not orientable")
        pieces += 1
    nxt: Dict[int, int] = {}
    for k in range(m):
        for c in range(3):
            if nb[k, c] >= 0:
                continue
            a, b = int(t[k, c]), int(t[k, (c + 1) % 3])
            if flip[k]:
                a, b = b, a
            if a in nxt:
                raise _MeshFault("non_manifold_mesh", k, None, "pinch", node=a)
            nxt[a] = b
    if not nxt:
        raise _MeshFault("no_boundary", -1, None, "triangle mesh has no boundary edge")
    return flip, piece, nxt


def boundary_loops(triangles: npt.ArrayLike) -> List[IntArray]:
    """Boundary loops of a consistently oriented triangle mesh: the directed edges
    whose reverse is absent, chained. Each loop starts at its smallest node."""
    t = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    edges = np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]], axis=0)
    und = np.sort(edges, axis=1)
    _, inv, counts = np.unique(und, axis=0, return_inverse=True, return_counts=True)
    inv = inv.reshape(-1)
    if (counts > 2).any():
        e = edges[int(np.flatnonzero(counts[inv] > 2)[0])]
        raise InvalidScene(f"edge {e.tolist()} is shared by more than two triangles", code="non_manifold_mesh")
    directed = {(int(a), int(b)) for a, b in edges}
    if len(directed) != len(edges):
        raise InvalidScene("two triangles run along an edge in the same direction: orient them first",
                           code="non_manifold_mesh")
    nxt: Dict[int, int] = {}
    for a, b in edges:
        a, b = int(a), int(b)
        if (b, a) not in directed:
            if a in nxt:
                raise InvalidScene(f"node {a} is a pinch point of the boundary (two bodies touch at a node)",
                                   code="non_manifold_mesh")
            nxt[a] = b
    loops: List[IntArray] = []
    seen: set[int] = set()
    for start in sorted(nxt):
        if start in seen:
            continue
        loop = [start]
        seen.add(start)
        node = nxt[start]
        while node != start:
            if node in seen or node not in nxt:
                raise InvalidScene(f"boundary does not close at node {node}", code="non_manifold_mesh")
            loop.append(node)
            seen.add(node)
            node = nxt[node]
        loops.append(np.array(loop, dtype=np.int64))
    return loops


def loop_area(nodes: npt.ArrayLike, loop: Sequence[int]) -> float:
    """Signed area of a loop (positive when counter-clockwise)."""
    p = np.asarray(nodes, dtype=np.float64)[np.asarray(loop)]
    d = p - p[0]
    return 0.5 * float(np.sum(d[:-1, 0] * d[1:, 1] - d[:-1, 1] * d[1:, 0]))


def connected_components(triangles: npt.ArrayLike, n_points: int) -> IntArray:
    """Component label of each triangle (triangles sharing a node are connected),
    numbered in the order of their smallest node."""
    t = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    parent = np.arange(n_points, dtype=np.int64)

    def find(x: int) -> int:
        root = x
        while parent[root] != root:
            root = int(parent[root])
        while parent[x] != root:  # path compression
            parent[x], x = root, int(parent[x])
        return root

    for a, b, c in t:
        ra, rb, rc = find(int(a)), find(int(b)), find(int(c))
        r = min(ra, rb, rc)
        parent[ra] = parent[rb] = parent[rc] = r
    roots = np.array([find(int(a)) for a in t[:, 0]], dtype=np.int64)
    first_node: Dict[int, int] = {}
    for r, tri in zip(roots, t):
        first_node[int(r)] = min(first_node.get(int(r), 1 << 62), int(tri.min()))
    order = sorted(first_node, key=first_node.__getitem__)
    label = {r: i for i, r in enumerate(order)}
    return np.array([label[int(r)] for r in roots], dtype=np.int64)


def _read(mesh: Any) -> Any:
    """A ``meshio.Mesh`` from a path (or the mesh itself). A file that cannot be
    opened is an ``OSError`` (``FileNotFoundError``, ``IsADirectoryError``, ...);
    one meshio cannot read is an :class:`InvalidScene` (``invalid_mesh``) that
    says why. meshio's own prints (it writes to standard output, and exits
    the process on some files) are kept out of the way."""
    if not isinstance(mesh, (str, os.PathLike)):
        return mesh
    try:
        import meshio  # type: ignore[import-untyped]
    except ImportError as exc:  # pragma: no cover - depends on the install
        raise ImportError("reading mesh files needs meshio: pip install 'ntscontact[mesh]'") from exc
    path = os.fspath(mesh)
    with open(path, "rb"):  # FileNotFoundError, IsADirectoryError, PermissionError: the caller's to report
        pass
    said = io.StringIO()
    try:
        with contextlib.redirect_stdout(said), contextlib.redirect_stderr(said):
            return meshio.read(path)
    except (Exception, SystemExit) as exc:  # meshio raises many kinds, and SystemExit when no reader fits
        told = " ".join(line.strip() for line in said.getvalue().splitlines() if line.strip())
        reason = str(exc) if not isinstance(exc, SystemExit) and str(exc) else told or type(exc).__name__
        reason = re.sub(r"\x1b\[[0-9;]*m", "", reason)  # meshio's colours
        reason = re.sub(r"^Error: ", "", reason)
        raise InvalidScene(f"cannot read {path} as a mesh: {reason}", code="invalid_mesh") from None


def _check_planar(points: FloatArray, used: IntArray, mesh: Any) -> None:
    """A 3D mesh is refused as one: volume cells, or points of the triangles at
    more than one z (a constant z, a plane parallel to xy, is dropped)."""
    volumes = sorted({b.type for b in mesh.cells if b.type.rstrip("0123456789") in _VOLUME_CELLS})
    if volumes:
        raise InvalidScene(f"3D mesh: ntscontact is 2D (the mesh has {', '.join(volumes)} cells); give it a planar "
                           "mesh of triangles or quads in the xy plane", code="invalid_mesh")
    if points.shape[1] < 3 or used.size == 0:
        return
    z = points[used, 2]
    off = np.flatnonzero(z != z[0])
    if off.size:
        k = int(used[off[0]])
        raise InvalidScene(f"3D mesh: ntscontact is 2D, and the points of its cells do not share one z (mesh point "
                           f"{int(used[0])} at z = {float(z[0])!r}, mesh point {k} at z = {float(points[k, 2])!r}); give it a "
                           "planar mesh in the xy plane", code="invalid_mesh", where=f"mesh point {k}")


def _triangles_and_tags(mesh: Any, tag: Union[str, None, bool]) -> Tuple[IntArray, Optional[IntArray], str]:
    """All triangles of the mesh (quads split) and the tag of each (or None)."""
    blocks: List[IntArray] = []
    block_tags: List[Optional[np.ndarray]] = []
    names: List[str] = []
    cell_data: Dict[str, List[np.ndarray]] = dict(getattr(mesh, "cell_data", {}) or {})
    if tag is None:
        for name in _TAG_NAMES:
            if name in cell_data:
                names = [name]
                break
        else:
            names = [k for k, v in cell_data.items() if _is_integral_tag(v)][:1]
    elif tag is not False:
        if tag not in cell_data:
            raise KeyError(f"the mesh has no cell_data {tag!r} (it has {sorted(cell_data)})")
        names = [str(tag)]
    tag_name = names[0] if names else ""
    for bi, block in enumerate(mesh.cells):
        kind = block.type
        data = np.asarray(block.data, dtype=np.int64)
        tags = None
        if tag_name:
            arr = np.asarray(cell_data[tag_name][bi]).reshape(-1)
            tags = arr
        if kind in _TRIANGLE_CORNERS:
            tri = data[:, :3]
        elif kind in _QUAD_CORNERS:
            q = data[:, :4]
            tri = np.concatenate([q[:, [0, 1, 2]], q[:, [0, 2, 3]]], axis=0)
            tags = None if tags is None else np.concatenate([tags, tags])
        else:
            continue
        blocks.append(tri)
        block_tags.append(tags)
    if not blocks:
        _check_planar(np.zeros((0, 2)), np.zeros(0, dtype=np.int64), mesh)  # only volumes: a 3D mesh
        raise InvalidScene("the mesh has no triangle (or quad) cells", code="no_nodes")
    triangles = np.concatenate(blocks, axis=0)
    all_tags: Optional[IntArray] = None
    if tag_name:
        vals = np.concatenate([np.asarray(t) for t in block_tags if t is not None])
        if not np.all(np.isfinite(vals)) or not np.all(vals == np.round(vals)):
            raise InvalidScene(f"cell_data {tag_name!r} is not integer", code="invalid_type")
        all_tags = vals.astype(np.int64)
    return triangles, all_tags, tag_name


def _is_integral_tag(arrays: List[np.ndarray]) -> bool:
    try:
        vals = [np.asarray(a) for a in arrays]
        return all(v.ndim == 1 and v.dtype.kind in "iuf" for v in vals) and all(
            np.all(v == np.round(v)) for v in vals)
    except (TypeError, ValueError):
        return False


def _tag_names(mesh: Any) -> Dict[int, str]:
    """Names of the 2D physical groups (gmsh ``field_data``: name -> [tag, dim])."""
    out: Dict[int, str] = {}
    for name, value in (getattr(mesh, "field_data", {}) or {}).items():
        v = np.asarray(value).reshape(-1)
        if v.size >= 2 and int(v[1]) == 2:
            out[int(v[0])] = str(name)
    return out


def bodies_from_mesh(mesh: Any, *, tag: Union[str, None, bool] = None) -> List[MeshBody]:
    """The bodies of a mesh (a path or a ``meshio.Mesh``).

    ``tag``: the ``cell_data`` field that says which body a cell belongs to; None
    picks ``gmsh:physical`` (or another integer field) when present; False
    ignores tags. A tagged group with several connected pieces becomes one body
    per piece (ids ``"<tag>.<k>"``), since one body has one outer loop.
    """
    m = _read(mesh)
    points = np.asarray(m.points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] < 2:
        raise InvalidScene(f"mesh points have shape {points.shape}", code="invalid_type")
    xy = np.ascontiguousarray(points[:, :2])
    triangles, tags, _ = _triangles_and_tags(m, tag)
    used = np.unique(triangles)
    bad = ~np.isfinite(xy[used]).all(axis=1)
    if bad.any():
        node = int(used[np.flatnonzero(bad)[0]])
        raise InvalidScene(f"mesh point {node} is not finite", code="non_finite", where=f"mesh point {node}")
    _check_planar(points, used, m)
    groups: List[Tuple[BodyId, IntArray]] = []
    if tags is None:
        comp = connected_components(triangles, xy.shape[0])
        for c in range(int(comp.max()) + 1):
            groups.append((c, triangles[comp == c]))
    else:
        names = _tag_names(m)
        for value in np.unique(tags):
            base: BodyId = names.get(int(value), int(value))
            tri = triangles[tags == value]
            comp = connected_components(tri, xy.shape[0])
            k = int(comp.max()) + 1
            for c in range(k):
                groups.append((base if k == 1 else f"{base}.{c}", tri[comp == c]))
    bodies: List[MeshBody] = []
    for body_id, tri in groups:
        used = np.unique(tri)
        local = np.full(xy.shape[0], -1, dtype=np.int64)
        local[used] = np.arange(used.size, dtype=np.int64)
        nodes, local_tri = xy[used].copy(), local[tri]
        # the core's rule for a triangle body, at convert time (a pinch point, a folded edge, ...)
        check_triangles(nodes, local_tri, point_index=used, body=repr(body_id) if isinstance(
            body_id, str) else str(body_id))
        bodies.append(MeshBody(id=body_id, nodes=nodes, triangles=orient_ccw(nodes, local_tri), point_index=used))
    return bodies


def _physical_curve(mesh: Any, name: str) -> int:
    """The tag of the 1D physical group ``name`` (gmsh ``field_data``: name ->
    [tag, dim]); a name the mesh lacks, or a group of another dimension, is an
    :class:`InvalidScene` (``invalid_surface``) naming it and the curves there are."""
    field = {str(k): np.asarray(v).reshape(-1) for k, v in (getattr(mesh, "field_data", {}) or {}).items()}
    curves = sorted(k for k, v in field.items() if v.size >= 2 and int(v[1]) == 1)
    there = f"its physical curves: {', '.join(map(repr, curves))}" if curves else "it names no physical curve"
    where = f"physical group {name!r}"
    if name not in field:
        raise InvalidScene(f"the mesh has no physical group {name!r} ({there})", code="invalid_surface", where=where)
    v = field[name]
    if v.size < 2:
        raise InvalidScene(f"{name!r} is not a gmsh physical group ([tag, dim]: {v.tolist()}) ({there})",
                           code="invalid_surface", where=where)
    if int(v[1]) != 1:
        raise InvalidScene(f"physical group {name!r} is {int(v[1])}D, not a curve: a contact surface is made of "
                           f"line elements, a 1D physical group ({there})", code="invalid_surface", where=where)
    return int(v[0])


def _curve_lines(mesh: Any, name: str, tag: int) -> IntArray:
    """The end points (mesh points, (k, 2)) of the line elements of physical
    curve ``name`` (tag ``tag``): meshio's ``cell_sets[name]`` when it has them
    (MSH 4.1: every physical group of an entity, even when an entity is in
    several), else the line cells whose ``gmsh:physical`` is ``tag`` (MSH 2.2)."""
    blocks = list(mesh.cells)
    sets = (getattr(mesh, "cell_sets", {}) or {}).get(name)
    physical = (getattr(mesh, "cell_data", {}) or {}).get("gmsh:physical")
    lines: List[IntArray] = []
    for bi, block in enumerate(blocks):
        if not _LINE.match(block.type):
            continue
        data = np.asarray(block.data, dtype=np.int64)[:, :2]
        if sets is not None and len(sets) == len(blocks):
            pick = np.asarray(sets[bi] if sets[bi] is not None else [], dtype=np.int64).reshape(-1)
            lines.append(data[pick])
        elif physical is not None and len(physical) == len(blocks):
            lines.append(data[np.asarray(physical[bi]).reshape(-1) == tag])
        else:
            raise InvalidScene(f"cannot tell which line elements are in physical curve {name!r}: the mesh has no "
                               "gmsh:physical tag (or cell set) for each of its cell blocks", code="invalid_surface",
                               where=f"physical curve {name!r}")
    out = np.concatenate(lines) if lines else np.zeros((0, 2), dtype=np.int64)
    if out.shape[0] == 0:
        raise InvalidScene(f"physical curve {name!r} (tag {tag}) has no line elements in the mesh",
                           code="invalid_surface", where=f"physical curve {name!r}")
    return out


def surfaces_from_mesh(mesh: Any, bodies: Sequence[MeshBody], names: Sequence[str]) -> Dict[int, IntArray]:
    """The contact surfaces named by gmsh physical curves (docs/model.md §13).

    ``mesh`` is a path or a ``meshio.Mesh``, ``bodies`` its bodies
    (:func:`bodies_from_mesh`), ``names`` the physical curves (1D physical
    groups, by their names in the file's ``$PhysicalNames``, meshio's
    ``field_data``). Every line element of these curves must be an edge of
    exactly one body's boundary (its two mesh points map to that body's nodes
    through ``point_index``). Returns, for each body (by its place in
    ``bodies``) that owns some of these edges, its surface: the ``(m, 2)``
    node pairs (the body's numbering), along its boundary loops, each edge
    once however often the curves name it. Bodies that own none are absent.
    A name the mesh lacks, a group that is not 1D, a curve with no line
    elements, or a line on no body's boundary (or on two bodies', sharing its
    points) is an :class:`InvalidScene` (``invalid_surface``) naming the curve,
    the line's mesh points and where they are."""
    if isinstance(names, str):
        names = [names]
    m = _read(mesh)
    points = np.asarray(m.points, dtype=np.float64)
    owner: Dict[Tuple[int, int], List[int]] = {}
    loops = [b.loops() for b in bodies]
    for k, (b, body_loops) in enumerate(zip(bodies, loops)):
        for lp in body_loops:
            ends = b.point_index[lp], b.point_index[np.roll(lp, -1)]
            for e in zip(np.minimum(*ends).tolist(), np.maximum(*ends).tolist()):
                owner.setdefault(e, []).append(k)
    chosen: Dict[int, Set[Tuple[int, int]]] = {}
    for name in dict.fromkeys(names):  # each name once, in order
        tag = _physical_curve(m, name)
        for li, (p, q) in enumerate(_curve_lines(m, name, tag).tolist()):
            who = owner.get((min(p, q), max(p, q)), [])
            if len(who) != 1:
                at = f"mesh points {p} {tuple(points[p, :2].tolist())} and {q} {tuple(points[q, :2].tolist())}"
                if not who:
                    what = "is not an edge of any body's boundary"
                else:
                    what = (f"is an edge of the boundaries of bodies {', '.join(repr(bodies[k].id) for k in who)}, "
                            "which share these points: give each body its own nodes and curve")
                raise InvalidScene(f"physical curve {name!r}: line element {li} ({at}) {what}",
                                   code="invalid_surface", where=f"physical curve {name!r}, line element {li}")
            chosen.setdefault(who[0], set()).add((min(p, q), max(p, q)))
    out: Dict[int, IntArray] = {}
    for k, edges in chosen.items():
        pairs = []
        for lp in loops[k]:
            nxt = np.roll(lp, -1)
            for a, c in zip(lp.tolist(), nxt.tolist()):
                p, q = int(bodies[k].point_index[a]), int(bodies[k].point_index[c])
                if (min(p, q), max(p, q)) in edges:
                    pairs.append((a, c))
        out[k] = np.array(pairs, dtype=np.int64).reshape(-1, 2)
    return out


def scene_from_mesh(
    mesh: Any,
    *,
    penalty: Optional[float] = None,
    alpha: Optional[float] = None,
    search_radius: Optional[float] = None,
    periodic: Optional[Tuple[float, float]] = None,
    solver: Optional[str] = None,
    outputs: Optional[Sequence[str]] = None,
    tag: Union[str, None, bool] = None,
    boundary: str = "triangles",
    penalty_scaling: Optional[str] = None,
    surfaces: Optional[Sequence[str]] = None,
    other_bodies: str = "whole",
) -> Scene:
    """A :class:`Scene` from a mesh file or a ``meshio.Mesh``.

    ``penalty`` has no default that fits every scale: None leaves it unset (set
    ``scene.penalty`` before sending; the service requires it).

    ``boundary="triangles"`` sends each body as its (counter-clockwise) triangles,
    so forces come back for every node of the mesh body (interior nodes get zero);
    ``boundary="loops"`` sends only the boundary nodes, with their loops.

    ``penalty_scaling`` is ``options.penalty_scaling`` (``"length"``: a
    node's force is eps g times its tributary length, so its pressure is eps g).

    ``surfaces``: names of gmsh physical curves that make the bodies' contact
    surfaces (docs/model.md §13, :func:`surfaces_from_mesh`): a body that owns
    line elements of these curves gets them as its ``surface``, in either
    numbering. A body that owns none keeps its whole boundary
    (``other_bodies="whole"``, the default: naming the contact sides of some
    bodies leaves the others as they were), or takes part in nothing
    (``other_bodies="none"``).
    """
    if boundary not in ("triangles", "loops"):
        raise ValueError("boundary is 'triangles' or 'loops'")
    if other_bodies not in ("whole", "none"):
        raise ValueError("other_bodies is 'whole' or 'none'")
    if other_bodies == "none" and not surfaces:
        raise ValueError("other_bodies='none' needs surfaces: without them no body would take part in contact")
    if isinstance(surfaces, str):
        surfaces = [surfaces]
    m = _read(mesh)
    scene = Scene(penalty=penalty, alpha=alpha, search_radius=search_radius, periodic=periodic, solver=solver,
                  outputs=outputs, penalty_scaling=penalty_scaling)
    bodies = bodies_from_mesh(m, tag=tag)
    named = surfaces_from_mesh(m, bodies, surfaces) if surfaces else {}
    rest: Optional[IntArray] = np.zeros((0, 2), dtype=np.int64) if other_bodies == "none" else None
    for k, b in enumerate(bodies):
        surface = named.get(k, rest)
        if boundary == "triangles":
            scene.add_body(b.nodes, triangles=b.triangles, id=b.id, mesh_points=b.point_index, surface=surface)
        else:
            loops = b.loops()
            on = np.unique(np.concatenate(loops))
            local = np.full(b.nodes.shape[0], -1, dtype=np.int64)
            local[on] = np.arange(on.size, dtype=np.int64)
            scene.add_body(b.nodes[on], loops=[local[lp] for lp in loops], id=b.id, mesh_points=b.point_index[on],
                           surface=None if surface is None else local[surface])
    return scene

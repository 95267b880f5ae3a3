"""Scenes from mesh files (any format meshio reads), ``pip install ntscontact[mesh]``.

Bodies come from cell tags when the mesh has them (``gmsh:physical``, or another
integer ``cell_data`` field), otherwise from the connected components of the
triangles. Coordinates keep x and y (z is dropped); every triangle is oriented
counter-clockwise, so boundaries come out counter-clockwise (holes clockwise).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from typing import Any, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

from .errors import InvalidScene
from .scene import BodyId, Scene

__all__ = [
    "MeshBody",
    "bodies_from_mesh",
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


def orient_ccw(points: npt.ArrayLike, triangles: npt.ArrayLike) -> IntArray:
    """A copy of ``triangles`` with every triangle counter-clockwise. A zero-area
    triangle is an :class:`InvalidScene` (``degenerate_triangle``)."""
    p = np.asarray(points, dtype=np.float64)[:, :2]
    t = np.array(triangles, dtype=np.int64, copy=True).reshape(-1, 3)
    a, b, c = p[t[:, 0]], p[t[:, 1]], p[t[:, 2]]
    # twice the signed area, relative to the first corner for precision; zero
    # area by the core's rule (core/src/triangles.c): |e1 x e2| <= 64 eps |e1| |e2|
    e1, e2 = b - a, c - a
    cross = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    zero = ~(np.abs(cross) > 64.0 * np.finfo(np.float64).eps * np.hypot(e1[:, 0], e1[:, 1]) * np.hypot(e2[:, 0], e2[:, 1]))
    zero |= (t[:, 0] == t[:, 1]) | (t[:, 1] == t[:, 2]) | (t[:, 0] == t[:, 2])
    if zero.any():
        k = int(np.flatnonzero(zero)[0])
        raise InvalidScene(f"triangle {k} = {t[k].tolist()} has zero area", code="degenerate_triangle",
                           where=f"triangle {k}")
    flip = cross < 0.0
    t[flip, 1], t[flip, 2] = t[flip, 2].copy(), t[flip, 1].copy()
    return t


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
    if isinstance(mesh, (str, os.PathLike)):
        try:
            import meshio  # type: ignore[import-untyped]
        except ImportError as exc:  # pragma: no cover - depends on the install
            raise ImportError("reading mesh files needs meshio: pip install 'ntscontact[mesh]'") from exc
        return meshio.read(os.fspath(mesh))
    return mesh


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
    bad = ~np.isfinite(xy[np.unique(triangles)]).all(axis=1)
    if bad.any():
        node = int(np.unique(triangles)[np.flatnonzero(bad)[0]])
        raise InvalidScene(f"mesh point {node} is not finite", code="non_finite", where=f"mesh point {node}")
    triangles = orient_ccw(xy, triangles)
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
        bodies.append(MeshBody(id=body_id, nodes=xy[used].copy(), triangles=local[tri], point_index=used))
    return bodies


def scene_from_mesh(
    mesh: Any,
    *,
    penalty: float = 1.0,
    alpha: Optional[float] = None,
    search_radius: Optional[float] = None,
    periodic: Optional[Tuple[float, float]] = None,
    solver: Optional[str] = None,
    outputs: Optional[Sequence[str]] = None,
    tag: Union[str, None, bool] = None,
    boundary: str = "triangles",
) -> Scene:
    """A :class:`Scene` from a mesh file or a ``meshio.Mesh``.

    ``boundary="triangles"`` sends each body as its (counter-clockwise) triangles,
    so forces come back for every node of the mesh body (interior nodes get zero);
    ``boundary="loops"`` sends only the boundary nodes, with their loops.
    """
    if boundary not in ("triangles", "loops"):
        raise ValueError("boundary is 'triangles' or 'loops'")
    scene = Scene(penalty=penalty, alpha=alpha, search_radius=search_radius, periodic=periodic, solver=solver,
                  outputs=outputs)
    for b in bodies_from_mesh(mesh, tag=tag):
        if boundary == "triangles":
            scene.add_body(b.nodes, triangles=b.triangles, id=b.id, mesh_points=b.point_index)
        else:
            loops = b.loops()
            on = np.unique(np.concatenate(loops))
            local = np.full(b.nodes.shape[0], -1, dtype=np.int64)
            local[on] = np.arange(on.size, dtype=np.int64)
            scene.add_body(b.nodes[on], loops=[local[lp] for lp in loops], id=b.id, mesh_points=b.point_index[on])
    return scene

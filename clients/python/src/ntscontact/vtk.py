"""Results as VTK XML unstructured grids (``.vtu``) for ParaView, in the layout
of the C tool's ``ntscontact --vtk`` (codec/src/vtk.c):

- points: every node (global order, z = 0), then each active contact's closest point;
- cells: each surface segment (a line, interior on the left), then each active
  contact (a line from the slave node to its closest point);
- point data ``force``, ``pressure`` (0 when not asked for) and ``body``; cell
  data ``kind`` (0 segment, 1 contact), ``body``, ``surface`` (1 for a segment
  on its body's contact surface, docs/model.md §13, 0 off it, -1 for
  contacts), ``master_body``, ``gap``, ``normal``, ``contact_kind``,
  ``contact_force``; with friction on (docs/model.md §14) also
  ``tangential_force`` and ``friction_state`` (-1 segments, 0 frictionless,
  1 stick, 2 slip);
- field data ``energy``, ``virial``, ``contacts``, ``max_penetration``; with
  friction on, ``virial`` has ``yx`` too, and ``dissipation``.

Written with the standard library and numpy only (no VTK or meshio needed);
doubles in their shortest round-trip form.
"""

from __future__ import annotations

import os
from typing import Any, List, Tuple, Union

import numpy as np

__all__ = ["surface_loops", "on_surface", "write_vtu"]

_KINDS = {"segment": 0, "corner": 1, "vertex": 2}
_STATES = {"frictionless": 0, "stick": 1, "slip": 2}  # nts_friction_state


def _signed_area(p: np.ndarray) -> float:
    d = p - p[0]
    return 0.5 * float(np.sum(d[:-1, 0] * d[1:, 1] - d[:-1, 1] * d[1:, 0]) + d[-1, 0] * d[0, 1] - d[-1, 1] * d[0, 0])


def surface_loops(scene: Any) -> List[List[np.ndarray]]:
    """Each body's loops (local node indices), oriented as the service orients
    them: interior on the left (docs/model.md §2)."""
    from .mesh import boundary_loops, orient_ccw

    out: List[List[np.ndarray]] = []
    for body in scene:
        nodes = body.nodes
        if body.triangles is not None:
            out.append(boundary_loops(orient_ccw(nodes, body.triangles)))
            continue
        loops = body.loops if body.loops is not None else [np.arange(body.node_count)]
        areas = [_signed_area(nodes[lp]) for lp in loops]
        outer = int(np.argmax(np.abs(areas)))
        fixed = []
        for k, (lp, a) in enumerate(zip(loops, areas)):
            if (a > 0) != (k == outer):
                lp = np.concatenate([lp[:1], lp[1:][::-1]])  # reversed, keeping the first node
            fixed.append(np.asarray(lp))
        out.append(fixed)
    return out


def on_surface(body: Any, loops: List[np.ndarray]) -> List[np.ndarray]:
    """For each of ``loops`` (a body's, as :func:`surface_loops` gives them), a
    boolean per segment (from place k to k + 1): whether it is on the body's
    contact surface (``body.surface``; every segment when it has none)."""
    surface = getattr(body, "surface", None)
    if surface is None:
        return [np.ones(len(lp), dtype=bool) for lp in loops]
    n = body.node_count
    pairs = np.asarray(surface, dtype=np.int64).reshape(-1, 2)
    named = np.minimum(pairs[:, 0], pairs[:, 1]) * n + np.maximum(pairs[:, 0], pairs[:, 1])
    out = []
    for lp in loops:
        a, b = np.asarray(lp, dtype=np.int64), np.roll(np.asarray(lp, dtype=np.int64), -1)
        out.append(np.isin(np.minimum(a, b) * n + np.maximum(a, b), named))
    return out


def _fmt(v: float) -> str:
    return repr(float(v))


def _array(lines: List[str], kind: str, name: str, comps: int, values: Any) -> None:
    lines.append(f'<DataArray type="{kind}" Name="{name}" NumberOfComponents="{comps}" format="ascii">')
    arr = np.asarray(values)
    if kind.startswith("Float"):
        lines.append("\n".join(" ".join(_fmt(x) for x in np.atleast_1d(row)) for row in arr.reshape(len(arr), -1)))
    else:
        lines.append("\n".join(" ".join(str(int(x)) for x in np.atleast_1d(row)) for row in arr.reshape(len(arr), -1)))
    lines.append("</DataArray>")


def write_vtu(path: Union[str, "os.PathLike[str]"], scene: Any, result: Any, positions: Any = None) -> None:
    """Write ``result`` (its forces, and its contacts when asked for) over the
    geometry of ``scene`` at ``positions`` ((N, 2), global order; default the
    scene's own)."""
    x = scene.positions() if positions is None else np.asarray(positions, dtype=np.float64)
    n = len(x)
    ids = scene.body_ids
    index = {(type(i), i): k for k, i in enumerate(ids)}
    offsets = np.concatenate([[0], np.cumsum([b.node_count for b in scene])]).astype(np.int64)
    body_of_node = np.repeat(np.arange(len(ids)), np.diff(offsets))
    segs: List[Tuple[int, int, int]] = []
    flags: List[np.ndarray] = []
    for b, (body, loops) in enumerate(zip(scene, surface_loops(scene))):
        flags += on_surface(body, loops)
        for lp in loops:
            g = lp + offsets[b]
            segs += [(int(g[k]), int(g[(k + 1) % len(g)]), b) for k in range(len(g))]
    seg_surface = np.concatenate(flags).astype(np.int64) if flags else np.zeros(0, dtype=np.int64)
    contacts = list(result.contacts)
    c = len(contacts)
    forces = result.force_array() if result.forces else np.zeros((n, 2))
    pressure = result.pressure_array() if getattr(result, "pressure", None) else np.zeros(n)
    pts = np.vstack([x, np.array([ct.point for ct in contacts]).reshape(c, 2)])
    seg_arr = np.array([(a, b) for a, b, _ in segs], dtype=np.int64).reshape(-1, 2)
    t = x[seg_arr[:, 1]] - x[seg_arr[:, 0]] if len(segs) else np.zeros((0, 2))
    if scene.periodic is not None:
        box = np.array(scene.periodic)
        t = t - box * np.round(t / box)
    length = np.hypot(t[:, 0], t[:, 1])
    normals = np.c_[t[:, 1], -t[:, 0]] / np.where(length > 0, length, 1.0)[:, None]
    conn = np.vstack([seg_arr, np.array([(offsets[index[(type(ct.slave_body), ct.slave_body)]] + ct.slave_node, n + k)
                                         for k, ct in enumerate(contacts)], dtype=np.int64).reshape(c, 2)])
    s = result.summary
    lines = ['<?xml version="1.0"?>',
             '<VTKFile type="UnstructuredGrid" version="1.0" byte_order="LittleEndian">', "<UnstructuredGrid>",
             "<FieldData>"]
    virial = [s.virial[0, 0], s.virial[1, 1], s.virial[0, 1]] + ([s.virial[1, 0]] if s.friction else [])
    fields: List[Tuple[str, List[float]]] = [("energy", [s.energy]), ("virial", virial), ("contacts", [float(s.contacts)]),
                                             ("max_penetration", [s.max_penetration])]
    if s.friction:
        fields.append(("dissipation", [s.dissipation]))
    for name, vals in fields:
        lines.append(f'<DataArray type="Float64" Name="{name}" NumberOfTuples="1" NumberOfComponents="{len(vals)}" '
                     f'format="ascii">' + " ".join(_fmt(v) for v in vals) + "</DataArray>")
    lines += ["</FieldData>", f'<Piece NumberOfPoints="{n + c}" NumberOfCells="{len(segs) + c}">', "<Points>"]
    _array(lines, "Float64", "Points", 3, np.c_[pts, np.zeros(n + c)])
    lines += ["</Points>", "<Cells>"]
    _array(lines, "Int64", "connectivity", 1, conn.ravel())
    _array(lines, "Int64", "offsets", 1, 2 * np.arange(1, len(conn) + 1))
    _array(lines, "UInt8", "types", 1, np.full(len(conn), 3))
    lines += ["</Cells>", '<PointData Vectors="force">']
    _array(lines, "Float64", "force", 3, np.c_[np.vstack([forces, np.zeros((c, 2))]), np.zeros(n + c)])
    _array(lines, "Float64", "pressure", 1, np.concatenate([pressure, np.zeros(c)]))
    _array(lines, "Int32", "body", 1, np.concatenate([body_of_node,
                                                      [index[(type(ct.master_body), ct.master_body)] for ct in contacts]]))
    lines += ["</PointData>", '<CellData Normals="normal">']
    _array(lines, "Int32", "kind", 1, [0] * len(segs) + [1] * c)
    _array(lines, "Int32", "body", 1, [b for _, _, b in segs] +
           [index[(type(ct.slave_body), ct.slave_body)] for ct in contacts])
    _array(lines, "Int32", "surface", 1, np.concatenate([seg_surface, np.full(c, -1, dtype=np.int64)]))
    _array(lines, "Int32", "master_body", 1, [-1] * len(segs) +
           [index[(type(ct.master_body), ct.master_body)] for ct in contacts])
    _array(lines, "Float64", "gap", 1, [0.0] * len(segs) + [ct.gap for ct in contacts])
    _array(lines, "Float64", "normal", 3, np.c_[np.vstack([normals, np.array([ct.normal for ct in contacts]).reshape(c, 2)]),
                                                np.zeros(len(segs) + c)])
    _array(lines, "Int32", "contact_kind", 1, [-1] * len(segs) + [_KINDS.get(ct.kind, -1) for ct in contacts])
    _array(lines, "Float64", "contact_force", 3, np.c_[np.vstack([np.zeros((len(segs), 2)),
                                                                  np.array([ct.force for ct in contacts]).reshape(c, 2)]),
                                                       np.zeros(len(segs) + c)])
    if s.friction:
        tf = np.array([ct.tangential_force or (0.0, 0.0) for ct in contacts], dtype=np.float64).reshape(c, 2)
        _array(lines, "Float64", "tangential_force", 3, np.c_[np.vstack([np.zeros((len(segs), 2)), tf]),
                                                              np.zeros(len(segs) + c)])
        _array(lines, "Int32", "friction_state", 1, [-1] * len(segs) + [_STATES.get(ct.state or "", 0) for ct in contacts])
    lines += ["</CellData>", "</Piece>", "</UnstructuredGrid>", "</VTKFile>", ""]
    with open(path, "w", encoding="ascii") as fh:
        fh.write("\n".join(lines))

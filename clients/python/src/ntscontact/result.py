"""Results as numpy arrays and small dataclasses (``result.schema.json``)."""

from __future__ import annotations

import json
import sys
import warnings as _warnings
from dataclasses import dataclass, field
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

from .scene import BodyId

__all__ = ["Result", "Summary", "Contact", "Gap", "ResultWarning", "IncompleteResultWarning", "virial_matrix"]

FloatArray = npt.NDArray[np.float64]
Vec2 = Tuple[float, float]


def virial_matrix(v: Optional[Mapping[str, Any]]) -> FloatArray:
    """``{"xx", "yy", "xy", "yx"}`` to a 2x2 float64 array ``[[xx, xy], [yx, yy]]``
    (zeros when absent; ``yx`` is ``xy`` when the answer has none: without
    friction the virial is symmetric, docs/model.md (28))."""
    v = v or {}
    xx, yy, xy = (float(v.get(k, 0.0)) for k in ("xx", "yy", "xy"))
    yx = float(v.get("yx", xy))
    return np.array([[xx, xy], [yx, yy]], dtype=np.float64)


def _vec(v: Any) -> Vec2:
    if v is None:
        return (0.0, 0.0)
    return (float(v[0]), float(v[1]))


@dataclass(frozen=True)
class Contact:
    """One active contact: slave node ``slave_node`` of ``slave_body`` against the
    master body's feature ``kind`` ("segment", "corner" or "vertex") with nodes
    ``master_nodes`` and shape-function ``weights``; ``xi`` is the segment parameter
    s or the corner parameter. ``force`` acts on the slave; ``virial`` is
    ``(xx, yy, xy)`` (see :attr:`virial_tensor`)."""

    slave_body: BodyId
    slave_node: int
    master_body: BodyId
    kind: str
    master_nodes: Tuple[int, ...]
    weights: Tuple[float, ...]
    xi: float
    gap: float
    normal: Vec2
    point: Vec2
    force: Vec2
    virial: Tuple[float, float, float]
    #: Sessions that keep contacts: the index of the last step's contact of the
    #: same pair (-1: new), and whether it was at the same feature. None otherwise.
    previous: Optional[int] = None
    persisted: Optional[bool] = None
    #: Friction (docs/model.md §14; None without): the tangential part of
    #: ``force``, ``"stick"``, ``"slip"`` or ``"frictionless"``, this step's
    #: slip, and the anchor after the step (``{"kind", "nodes", "param"}``).
    tangential_force: Optional[Vec2] = None
    state: Optional[str] = None
    slip: Optional[float] = None
    anchor: Optional[Mapping[str, Any]] = None

    @property
    def virial_tensor(self) -> FloatArray:
        """``virial`` as the symmetric 2x2 array ``[[xx, xy], [xy, yy]]``."""
        xx, yy, xy = self.virial
        return np.array([[xx, xy], [xy, yy]], dtype=np.float64)

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "Contact":
        """A contact from one entry of a result's ``contacts``; fields the entry lacks
        (friction, session matches) stay ``None``."""
        s, m = d["slave"], d["master"]
        v = d.get("virial") or {}
        return cls(
            slave_body=s["body"],
            slave_node=int(s["node"]),
            master_body=m["body"],
            kind=str(m.get("kind", "")),
            master_nodes=tuple(int(i) for i in m.get("nodes", ())),
            weights=tuple(float(w) for w in m.get("weights", ())),
            xi=float(m.get("xi", 0.0)),
            gap=float(d["gap"]),
            normal=_vec(d.get("normal")),
            point=_vec(d.get("point")),
            force=_vec(d.get("force")),
            virial=(float(v.get("xx", 0.0)), float(v.get("yy", 0.0)), float(v.get("xy", 0.0))),
            previous=int(d["previous"]) if "previous" in d else None,
            persisted=bool(d["persisted"]) if "persisted" in d else None,
            tangential_force=_vec(d["tangential_force"]) if "tangential_force" in d else None,
            state=str(d["state"]) if "state" in d else None,
            slip=float(d["slip"]) if "slip" in d else None,
            anchor=d.get("anchor"),
        )


@dataclass(frozen=True)
class Gap:
    """The closest point of a slave node on another body within the search radius,
    active (``gap < 0``) or not. Fields the service adds beyond ``gap`` (kind,
    nodes, normal, ...) are kept in ``extra``."""

    slave_body: BodyId
    slave_node: int
    master_body: BodyId
    gap: float
    extra: Mapping[str, Any] = field(default_factory=dict, compare=False, repr=False)

    @property
    def active(self) -> bool:
        """Whether the closest point is an active contact (``gap < 0``)."""
        return self.gap < 0.0

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "Gap":
        """A gap from one entry of a result's ``gaps``: the slave, the master body and
        ``gap``; everything else of the entry and of its master in ``extra``."""
        s, m = d["slave"], d["master"]
        extra = {k: v for k, v in d.items() if k not in ("slave", "gap")}
        extra.update({k: v for k, v in m.items() if k != "body"})
        extra.pop("master", None)
        return cls(slave_body=s["body"], slave_node=int(s["node"]), master_body=m["body"], gap=float(d["gap"]),
                   extra=extra)


class IncompleteResultWarning(UserWarning):
    """Raised through :func:`warnings.warn` when a result says it may lack
    something (its ``warnings``): e.g. ``penetration_beyond_radius``, active
    contacts deeper than an explicit search radius, left out."""


def user_stacklevel() -> int:
    """The ``stacklevel`` for :func:`warnings.warn`, called from the function
    that warns, that names the first caller outside this package: the
    user's line, however many of the client's own calls lie between
    (``Session.step`` calls ``contact``; a distributed session's ``contact``
    calls its base's)."""
    level, frame = 1, sys._getframe(1)
    while frame.f_back is not None and str(frame.f_globals.get("__name__", "")).partition(".")[0] == "ntscontact":
        frame, level = frame.f_back, level + 1
    return level


@dataclass(frozen=True)
class ResultWarning:
    """One entry of a result's ``warnings``: a stable ``code``, how many
    contacts (or nodes) it concerns, and the service's ``message``."""

    code: str
    count: int
    message: str = ""

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "ResultWarning":
        """A warning from one entry of a result's ``warnings`` (missing fields: empty or 0)."""
        return cls(code=str(d.get("code", "")), count=int(d.get("count", 0)), message=str(d.get("message", "")))

    @classmethod
    def from_header(cls, value: str) -> List["ResultWarning"]:
        """The ``NTS-Warnings`` header of a binary answer: ``code=count, ...``."""
        out: List[ResultWarning] = []
        for part in value.split(","):
            code, _, count = part.strip().partition("=")
            if code:
                out.append(cls(code=code, count=int(count or 0)))
        return out


@dataclass(frozen=True)
class Summary:
    """``summary`` of a result (always complete). ``virial`` is a 2x2 array."""

    bodies: int
    nodes: int
    surface_nodes: int
    contacts: int
    gaps: int
    energy: float
    virial: FloatArray = field(compare=False)
    max_penetration: float
    loops_reversed: int
    search_radius: float
    cell_size: float
    elapsed_ms: float = field(compare=False)
    #: Of the active contacts, those deeper than the (default) search radius.
    deep_contacts: int = 0
    extra: Mapping[str, Any] = field(default_factory=dict, compare=False, repr=False)
    #: Friction (docs/model.md §14; 0 without): the work the slipping contacts
    #: turned into heat this step, and the active contacts sticking and slipping.
    dissipation: float = 0.0
    sticking: int = 0
    slipping: int = 0
    #: Whether friction was on (the answer had these three and the virial's yx).
    friction: bool = False

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "Summary":
        """A summary from a result's ``summary`` (missing fields: 0); fields the client
        does not know are kept in ``extra``."""
        known = ("bodies", "nodes", "surface_nodes", "contacts", "gaps", "energy", "virial", "max_penetration",
                 "loops_reversed", "search_radius", "cell_size", "elapsed_ms", "deep_contacts", "dissipation",
                 "sticking", "slipping")
        return cls(
            bodies=int(d.get("bodies", 0)),
            nodes=int(d.get("nodes", 0)),
            surface_nodes=int(d.get("surface_nodes", 0)),
            contacts=int(d.get("contacts", 0)),
            gaps=int(d.get("gaps", 0)),
            energy=float(d.get("energy", 0.0)),
            virial=virial_matrix(d.get("virial")),
            max_penetration=float(d.get("max_penetration", 0.0)),
            loops_reversed=int(d.get("loops_reversed", 0)),
            search_radius=float(d.get("search_radius", 0.0)),
            cell_size=float(d.get("cell_size", 0.0)),
            elapsed_ms=float(d.get("elapsed_ms", 0.0)),
            deep_contacts=int(d.get("deep_contacts", 0)),
            extra={k: v for k, v in d.items() if k not in known},
            dissipation=float(d.get("dissipation", 0.0)),
            sticking=int(d.get("sticking", 0)),
            slipping=int(d.get("slipping", 0)),
            friction="dissipation" in d,
        )


@dataclass
class Result:
    """The answer of ``POST /v1/contact``.

    ``forces`` maps each body id to an ``(n, 2)`` float64 array aligned with the
    nodes that were sent (empty when ``forces`` was not asked for); ``pressure``
    maps each body id to an ``(n,)`` float64 array of the normal contact
    traction on each node as a slave (docs/model.md (21); empty when
    ``pressure`` was not asked for); ``energy`` and
    ``virial`` (2x2) come from the summary; ``contacts`` and ``gaps`` are lists,
    empty unless asked for in ``outputs``; ``warnings`` says what the result
    may lack (empty: nothing); ``raw`` is the parsed JSON.
    """

    summary: Summary
    forces: Mapping[BodyId, FloatArray]
    contacts: List[Contact]
    gaps: List[Gap]
    raw: Dict[str, Any] = field(repr=False)
    warnings: List[ResultWarning] = field(default_factory=list)
    pressure: Mapping[BodyId, FloatArray] = field(default_factory=dict)
    #: A binary session answer's (N, 2) forces; ``forces`` holds views into it.
    _force_array: Optional[FloatArray] = field(default=None, repr=False, compare=False)
    #: The tangent's triplets (rows, cols, values, size) of a binary answer.
    _triplets: Optional[Tuple[Any, Any, Any, int]] = field(default=None, repr=False, compare=False)
    #: (scene, positions evaluated) when the client knows them (to_vtk, plot); the
    #: scene may be a function that builds it.
    _scene: Any = field(default=None, repr=False, compare=False)

    def stiffness_triplets(self) -> Tuple[npt.NDArray[np.int64], npt.NDArray[np.int64], FloatArray, int]:
        """The tangent ``K = d2E/dx2 = -df/dx`` as triplets ``(rows, cols, values,
        size)`` over dof ``2 node + component`` (global node order); duplicates
        sum. Raises ``KeyError`` when ``outputs`` did not ask for stiffness."""
        if self._triplets is not None:
            rows, cols, values, size = self._triplets
            return (np.asarray(rows, dtype=np.int64), np.asarray(cols, dtype=np.int64),
                    np.asarray(values, dtype=np.float64), int(size))
        k = self.raw.get("stiffness")
        if not isinstance(k, Mapping):
            raise KeyError("this result has no stiffness: ask for outputs=[..., 'stiffness']")
        return (np.asarray(k["rows"], dtype=np.int64), np.asarray(k["cols"], dtype=np.int64),
                np.asarray(k["values"], dtype=np.float64), int(k["size"]))

    @property
    def stiffness(self) -> Any:
        """The tangent as a ``scipy.sparse.csr_matrix`` of shape (2N, 2N), the
        duplicates summed (``pip install 'ntscontact[sparse]'``)."""
        try:
            import scipy.sparse  # type: ignore[import-untyped]
        except ImportError as exc:  # pragma: no cover - depends on the install
            raise ImportError("Result.stiffness needs scipy: pip install 'ntscontact[sparse]' (or use "
                              "Result.stiffness_triplets())") from exc
        rows, cols, values, size = self.stiffness_triplets()
        return scipy.sparse.csr_matrix((values, (rows, cols)), shape=(size, size))

    @property
    def history(self) -> Optional[List[Dict[str, Any]]]:
        """With friction (docs/model.md §14): the anchors after this step, as
        the service gives them (``[{"slave": {"body", "node"}, "master",
        "kind", "nodes", "param"}, ...]``); pass it back as a stateless call's
        ``history`` (``Client.contact(scene, history=...)``) to go on from this
        step. None without friction, and for a binary session answer (a
        session keeps its own)."""
        h = self.raw.get("history")
        return list(h) if isinstance(h, list) else None

    def tangential_forces(self) -> FloatArray:
        """The contacts' tangential forces (on the slave), ``(m, 2)`` in contact
        order (zeros without friction; needs ``contacts`` in ``outputs``)."""
        return np.array([c.tangential_force or (0.0, 0.0) for c in self.contacts],
                        dtype=np.float64).reshape(len(self.contacts), 2)

    @property
    def energy(self) -> float:
        """The contact energy, ``summary.energy``."""
        return self.summary.energy

    @property
    def virial(self) -> FloatArray:
        """The 2x2 virial, ``summary.virial``."""
        return self.summary.virial

    @property
    def body_ids(self) -> List[BodyId]:
        """The ids of the bodies that have forces, in the order of the answer."""
        return list(self.forces)

    def force_array(self, order: Optional[Sequence[BodyId]] = None) -> FloatArray:
        """All forces stacked into one ``(N, 2)`` array, bodies in ``order`` (default:
        the order of the answer, which is the order of the scene: the global node
        order of sessions). A binary session answer gives its array as it came,
        read-only and without a copy."""
        if order is None and self._force_array is not None:
            return self._force_array
        ids = list(self.forces) if order is None else list(order)
        if not ids:
            return np.zeros((0, 2), dtype=np.float64)
        return np.concatenate([self.forces[i] for i in ids], axis=0)

    def pressure_array(self, order: Optional[Sequence[BodyId]] = None) -> FloatArray:
        """All pressures stacked into one ``(N,)`` array, bodies in ``order``
        (default: the order of the answer). Raises ``KeyError`` when ``outputs``
        did not ask for pressure."""
        if not self.pressure:
            raise KeyError("this result has no pressure: ask for outputs=[..., 'pressure']")
        ids = list(self.pressure) if order is None else list(order)
        return np.concatenate([self.pressure[i] for i in ids], axis=0)

    def contact_arrays(self) -> Dict[str, npt.NDArray[Any]]:
        """Contacts as columns, for vectorised work over them: ``slave_body`` and
        ``master_body`` (the ids, an object array), ``slave_body_index`` and
        ``master_body_index`` (the bodies' places in the scene, -1 when the
        result does not list the bodies), ``slave_node`` (m,), ``master_nodes``
        and ``weights`` (m, 3; -1 and 0 where a feature has fewer nodes),
        ``kind`` (m,) as 0 segment, 1 corner, 2 vertex, ``xi`` (m,), ``gap``
        (m,), ``normal``, ``point``, ``force`` (m, 2), ``virial`` (m, 3) as
        (xx, yy, xy)."""
        m = len(self.contacts)
        order = {(type(i), i): k for k, i in enumerate(self.body_ids)}
        kinds = {"segment": 0, "corner": 1, "vertex": 2}
        nodes = np.full((m, 3), -1, dtype=np.int64)
        weights = np.zeros((m, 3), dtype=np.float64)
        for k, c in enumerate(self.contacts):
            nodes[k, :len(c.master_nodes)] = c.master_nodes
            weights[k, :len(c.weights)] = c.weights
        return {
            "slave_body": np.array([c.slave_body for c in self.contacts], dtype=object),
            "master_body": np.array([c.master_body for c in self.contacts], dtype=object),
            "slave_body_index": np.array([order.get((type(c.slave_body), c.slave_body), -1) for c in self.contacts],
                                         dtype=np.int64),
            "master_body_index": np.array([order.get((type(c.master_body), c.master_body), -1)
                                           for c in self.contacts], dtype=np.int64),
            "master_nodes": nodes,
            "weights": weights,
            "kind": np.array([kinds.get(c.kind, -1) for c in self.contacts], dtype=np.int64),
            "xi": np.array([c.xi for c in self.contacts], dtype=np.float64),
            "slave_node": np.array([c.slave_node for c in self.contacts], dtype=np.int64),
            "gap": np.array([c.gap for c in self.contacts], dtype=np.float64),
            "normal": np.array([c.normal for c in self.contacts], dtype=np.float64).reshape(m, 2),
            "point": np.array([c.point for c in self.contacts], dtype=np.float64).reshape(m, 2),
            "force": np.array([c.force for c in self.contacts], dtype=np.float64).reshape(m, 2),
            "virial": np.array([c.virial for c in self.contacts], dtype=np.float64).reshape(m, 3),
        }

    def _positions(self) -> Any:
        """The positions this result was evaluated at, when the client knows
        them (made on demand after a surface exchange's step), else None."""
        if self._scene is None:
            return None
        positions = self._scene[1]
        return positions() if callable(positions) else positions

    def to_vtk(self, path: Any, scene: Any = None) -> None:
        """Write a ParaView file (``.vtu``): surfaces, forces, contacts with
        their gaps and normals (:mod:`ntscontact.vtk`). ``scene`` is the scene at
        the evaluated positions; a result of ``Client.contact(scene)`` or of a
        session step knows it already."""
        from .vtk import write_vtu

        positions = None
        if scene is None and self._scene is not None:
            scene, positions = self._scene
            scene = scene() if callable(scene) else scene
            positions = self._positions()
        if scene is None:
            raise ValueError("to_vtk needs the scene the result belongs to: to_vtk(path, scene)")
        write_vtu(path, scene, self, positions)

    def forces_on_mesh(self, scene: Any, mesh_points: Optional[int] = None) -> FloatArray:
        """The forces put back on the points of the mesh the scene was converted
        from (each body's ``mesh_points``, which ``python -m ntscontact convert``
        and ``scene_from_mesh`` keep): a (P, 2) array, P = ``mesh_points`` or the
        largest index + 1; a point shared by two bodies gets the sum."""
        maps = {b.id: b.mesh_points for b in scene}
        missing = [i for i, m in maps.items() if m is None and i in self.forces]
        if missing:
            raise ValueError(f"body {missing[0]!r} has no mesh_points: it was not converted from a mesh")
        size = mesh_points if mesh_points is not None else 1 + max(int(m.max()) for m in maps.values() if m is not None)
        out = np.zeros((int(size), 2), dtype=np.float64)
        for body_id, f in self.forces.items():
            np.add.at(out, np.asarray(maps[body_id], dtype=np.int64), f)
        return out

    @classmethod
    def from_dict(cls, doc: Mapping[str, Any]) -> "Result":
        """A result from a parsed result document (``POST /v1/contact``'s answer);
        ``raw`` keeps the document."""
        forces: Dict[BodyId, FloatArray] = {}
        pressure: Dict[BodyId, FloatArray] = {}
        for b in doc.get("bodies") or []:
            p = b.get("pressure")
            if p is not None:
                pressure[b["id"]] = np.array(p, dtype=np.float64).reshape(-1)
            f = b.get("forces")
            if f is None:
                continue
            arr = np.array(f, dtype=np.float64)
            forces[b["id"]] = arr.reshape(-1, 2) if arr.size else np.zeros((0, 2), dtype=np.float64)
        return cls(
            summary=Summary.from_dict(doc.get("summary") or {}),
            forces=forces,
            contacts=[Contact.from_dict(c) for c in doc.get("contacts") or []],
            gaps=[Gap.from_dict(g) for g in doc.get("gaps") or []],
            raw=dict(doc),
            warnings=[ResultWarning.from_dict(w) for w in doc.get("warnings") or []],
            pressure=pressure,
        )

    def warn(self) -> "Result":
        """Pass each of the result's ``warnings`` to :func:`warnings.warn` as an
        :class:`IncompleteResultWarning` (the client does, for every answer it
        receives); returns the result."""
        for w in self.warnings:
            text = f"{w.code} ({w.count})" + (f": {w.message}" if w.message else "")
            _warnings.warn(text, IncompleteResultWarning, stacklevel=user_stacklevel())
        return self

    @classmethod
    def from_json(cls, text: Union[str, bytes]) -> "Result":
        """A result from JSON text (:meth:`from_dict` of it)."""
        return cls.from_dict(json.loads(text))

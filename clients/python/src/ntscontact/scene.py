"""Scenes built from numpy arrays, checked before they are sent.

A :class:`Scene` is the request of ``scene.schema.json``: options and bodies. A body
has nodes (an ``(n, 2)`` array) and either ``loops`` (lists of node indices,
counter-clockwise outer loops) or ``triangles`` (an ``(m, 3)`` linear triangle
mesh whose boundary the service extracts), or neither (one loop through all
nodes in order), and optionally a ``surface``: the boundary segments (node
pairs) that take part in contact (docs/model.md §13; default the whole boundary).
"""

from __future__ import annotations

import itertools
import json
import math
import os
from dataclasses import dataclass
from typing import Any, Dict, Iterator, List, Mapping, Optional, Sequence, Set, Tuple, Union

import numpy as np
import numpy.typing as npt

from .errors import InvalidScene

__all__ = ["Body", "BodyId", "Scene", "OUTPUTS", "SOLVERS"]

BodyId = Union[str, int]
ArrayLike = npt.ArrayLike
FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
#: Loops: a list of index sequences (or one flat sequence for a single loop).
LoopsLike = Union[Sequence[ArrayLike], npt.NDArray[Any]]

#: The outputs a scene may ask for (``options.outputs``).
OUTPUTS: Tuple[str, ...] = ("forces", "energy", "virial", "contacts", "gaps", "stiffness", "pressure")
#: The corner solvers of the service (``options.solver``).
SOLVERS: Tuple[str, ...] = ("closed_form", "newton")


def body_key(body_id: Any) -> Tuple[type, Any]:
    """What a body is looked up by: its id's type and value (1 and "1" are
    two bodies), a numpy integer read as the int it is."""
    if isinstance(body_id, np.integer):
        body_id = int(body_id)
    return (type(body_id), body_id)


def is_number(value: Any) -> bool:
    """A Python or numpy number, not a boolean (which is an int to Python)."""
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))


def is_integer(value: Any) -> bool:
    """A Python or numpy integer, not a boolean."""
    return isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_))


def option_number(value: Any, pointer: str, where: str = "") -> float:
    """A numeric option as the float it is (as float() reads it); a boolean,
    which float() reads as 0 or 1, refused as the service refuses it:
    ``invalid_type`` at ``pointer``."""
    if isinstance(value, (bool, np.bool_)):
        raise InvalidScene("expected a number, got a boolean", code="invalid_type", pointer=pointer, where=where)
    return float(value)


def _where(index: int, body_id: Any) -> str:
    return f"body {body_id!r} (index {index})"


def _as_index_array(value: Any, what: str, index: int, body_id: Any, pointer: str,
                    n: Optional[int] = None) -> IntArray:
    """Integer array from ints (or integral floats), refused before the cast
    as the service refuses it, at the entry's pointer and with the value as
    given: a float that is not an integer ``invalid_value``, a value beyond
    int64 ``index_out_of_range`` (of ``[0, n)`` when ``n``, a body's node
    count, is given). Anything else that is not integers is ``invalid_type``."""
    where = _where(index, body_id)
    at = _first_bool(value)
    if at is not None:  # (numpy would read a True among ints as 1)
        raise InvalidScene("expected an integer node index, got a boolean", code="invalid_type",
                           pointer=pointer + "".join(f"/{i}" for i in at), where=f"{where}, {what} entry {at}")
    try:
        arr = np.asarray(value)
    except (TypeError, ValueError) as exc:  # ragged nested lists
        raise InvalidScene(f"{what} is not a rectangular array of integers ({exc})",
                           code="invalid_type", pointer=pointer, where=where) from None
    if arr.size == 0:
        return arr.astype(np.int64).reshape(arr.shape)
    noun = "node index" if n is not None else "index"
    span = f"out of range [0, {n})" if n is not None else "beyond 64 bits"
    if arr.dtype.kind == "O":  # Python ints beyond 64 bits, which numpy keeps as objects
        for flat, item in enumerate(arr.flat):
            if isinstance(item, int) and not -2**63 <= item < 2**63:
                pos = [int(i) for i in np.unravel_index(flat, arr.shape)]
                raise InvalidScene(f"{noun} {item!r} is {span}", code="index_out_of_range",
                                   pointer=pointer + "".join(f"/{i}" for i in pos), where=f"{where}, {what} entry {pos}")
    if arr.dtype.kind not in "iuf":
        raise InvalidScene(f"{what} must hold integer node indices", code="invalid_type", pointer=pointer,
                           where=where)

    def refuse(bad: npt.NDArray[np.bool_], code: str, words: str) -> None:
        if bad.any():
            at = [int(i) for i in np.unravel_index(int(np.flatnonzero(bad)[0]), arr.shape)]
            given = value  # (not arr's: numpy reads a list's int beyond int64 as a float)
            for i in at:
                given = given[i]
            raise InvalidScene(words.format(v=given.item() if isinstance(given, np.generic) else given), code=code,
                               pointer=pointer + "".join(f"/{i}" for i in at), where=f"{where}, {what} entry {at}")

    if arr.dtype.kind == "f":
        refuse(~(np.isfinite(arr) & (arr == np.floor(arr))), "invalid_value",
               f"a {noun} must be an integer, got {{v!r}}")
    if arr.dtype.kind == "f" or arr.dtype == np.uint64:  # beyond int64, which the cast would wrap
        beyond = np.abs(arr) >= 2.0 ** 63 if arr.dtype.kind == "f" else arr > np.iinfo(np.int64).max
        refuse(beyond, "index_out_of_range", f"{noun} {{v!r}} is {span}")
    return arr.astype(np.int64)


def _first_bool(value: Any) -> Optional[List[int]]:
    """Where the first boolean of an index list lies (a list of indices, or
    of rows: numpy would read True among ints as 1), else None. A numpy
    array is numpy's to type."""
    if not isinstance(value, (list, tuple)):
        return None
    kinds = set(map(type, value))
    if kinds <= {list, tuple}:  # rows: their entries' types, at C speed
        kinds = set(map(type, itertools.chain.from_iterable(value)))
    if not kinds & {bool, np.bool_, np.ndarray}:
        return None
    for i, row in enumerate(value):
        if isinstance(row, (bool, np.bool_)):
            return [i]
        if isinstance(row, np.ndarray) and row.dtype.kind == "b" and row.size:
            return [i] + [0] * row.ndim
        if isinstance(row, (list, tuple)):
            for j, x in enumerate(row):
                if isinstance(x, (bool, np.bool_)):
                    return [i, j]
    return None


def _is_pair_list(value: Any) -> bool:
    """What the service reads as a JSON array: a list, a tuple or a 1-D numpy array."""
    return isinstance(value, (list, tuple)) or (isinstance(value, np.ndarray) and value.ndim == 1)


def _surface_index(value: Any, n: int, pointer: str, where: str) -> int:
    """One node index of a surface pair, refused as the service refuses it: not
    a number (a boolean included) ``invalid_type``, not an integer
    ``invalid_value``, outside ``[0, n)`` ``index_out_of_range``."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise InvalidScene(f"expected an integer node index, got {type(value).__name__}", code="invalid_type",
                           pointer=pointer, where=where)
    if isinstance(value, (float, np.floating)) and not (math.isfinite(value) and value == math.floor(value)):
        raise InvalidScene(f"a node index must be an integer, got {value!r}", code="invalid_value", pointer=pointer,
                           where=where)
    if not 0 <= value < n:
        raise InvalidScene(f"node index {value!r} is out of range [0, {n})", code="index_out_of_range",
                           pointer=pointer, where=where)
    return int(value)


def as_surface(surface: Any, n: int, index: int = 0, body_id: Any = None) -> IntArray:
    """A body's contact surface as an ``(m, 2)`` int64 array of node pairs,
    refused with the code and JSON pointer the service gives (``codec/src/decode.c``,
    in its order): not a list ``invalid_type`` at ``/bodies/B/surface``; more
    pairs than the body has nodes ``invalid_value`` there; pair K not a list
    ``invalid_type`` at ``.../K``, not two entries ``invalid_value`` (at
    ``.../K/2`` for a third one); an entry C not an integer node index in
    ``[0, n)`` ``invalid_type``, ``invalid_value`` or ``index_out_of_range`` at
    ``.../K/C``. Whether each pair is a boundary segment is
    :func:`check_surface_segments`'s."""
    where = _where(index, body_id)
    pointer = f"/bodies/{index}/surface"
    if isinstance(surface, np.ndarray) and surface.ndim == 2 and surface.shape[1] == 2 and \
            surface.dtype.kind in "iuf":  # the fast path: numbers in the right shape
        if surface.shape[0] > n:
            raise InvalidScene(f"{surface.shape[0]} surface segments for a body of {n} nodes (each boundary segment "
                               "at most once)", code="invalid_value", pointer=pointer, where=where)
        arr = surface.astype(np.float64) if surface.dtype.kind == "f" else surface
        integral = np.isfinite(arr) & (arr == np.floor(arr)) if arr.dtype.kind == "f" else np.ones(arr.shape, bool)
        bad = ~integral | (arr < 0) | (arr >= n)
        if bad.any():
            k, c = divmod(int(np.flatnonzero(bad.ravel())[0]), 2)
            v = surface[k, c]
            _surface_index(v.item(), n, f"{pointer}/{k}/{c}", f"{where}, surface pair {k}")
        return surface.astype(np.int64)
    if isinstance(surface, np.ndarray):
        surface = surface.tolist()
    if not _is_pair_list(surface):
        raise InvalidScene(f"surface must be a list of boundary segments [i, j], got {type(surface).__name__}",
                           code="invalid_type", pointer=pointer, where=where)
    pairs = list(surface)
    if len(pairs) > n:
        raise InvalidScene(f"{len(pairs)} surface segments for a body of {n} nodes (each boundary segment at most "
                           "once)", code="invalid_value", pointer=pointer, where=where)
    out = np.empty((len(pairs), 2), dtype=np.int64)
    for k, pair in enumerate(pairs):
        ptr, at = f"{pointer}/{k}", f"{where}, surface pair {k}"
        if not _is_pair_list(pair):
            raise InvalidScene(f"a surface segment is a pair [i, j] of node indices, got {type(pair).__name__}",
                               code="invalid_type", pointer=ptr, where=at)
        count = 0
        for c, v in enumerate(pair):
            if c >= 2:
                raise InvalidScene("a surface segment has exactly two node indices", code="invalid_value",
                                   pointer=f"{ptr}/{c}", where=at)
            out[k, c] = _surface_index(v.item() if isinstance(v, np.generic) else v, n, f"{ptr}/{c}", at)
            count += 1
        if count != 2:
            raise InvalidScene("a surface segment has exactly two node indices", code="invalid_value", pointer=ptr,
                               where=at)
    return out


def check_surface_segments(surface: IntArray, loops: Sequence[IntArray], n: int, index: int = 0,
                           body_id: Any = None) -> None:
    """Each pair of ``surface`` is a segment of ``loops`` (either direction), each
    segment once: the core's rule (``mark_surfaces`` in ``core/src/scene.c``),
    with its code and pointer: the first pair that is not a segment, or repeats
    an earlier one, is ``invalid_surface`` at ``/bodies/B/surface/K``."""
    if surface.shape[0] == 0:
        return
    ends = np.concatenate([np.stack([lp, np.roll(lp, -1)], axis=1) for lp in loops]).astype(np.int64)
    segs = np.unique(np.minimum(ends[:, 0], ends[:, 1]) * n + np.maximum(ends[:, 0], ends[:, 1]))
    lo, hi = np.minimum(surface[:, 0], surface[:, 1]), np.maximum(surface[:, 0], surface[:, 1])
    codes = lo * n + hi
    pos = np.minimum(np.searchsorted(segs, codes), segs.size - 1)
    is_seg = (segs[pos] == codes) & (lo != hi)
    _, first = np.unique(codes, return_index=True)
    repeat = np.ones(codes.size, dtype=bool)
    repeat[first] = False
    bad = ~is_seg | repeat
    if not bad.any():
        return
    k = int(np.flatnonzero(bad)[0])
    i, j = int(surface[k, 0]), int(surface[k, 1])
    what = (f"nodes {i} and {j} are not the ends of a segment of its boundary" if not is_seg[k] else
            f"the segment from node {i} to node {j} is on the surface already (each segment once)")
    raise InvalidScene(f"surface pair {k}: {what}", code="invalid_surface", pointer=f"/bodies/{index}/surface/{k}",
                       where=f"{_where(index, body_id)}, surface pair {k}")


def as_nodes(nodes: ArrayLike, index: int = 0, body_id: Any = None, field: str = "nodes") -> FloatArray:
    """An ``(n, 2)`` C-contiguous float64 copy of ``nodes``, checked for shape and
    finiteness; the error names the body and the first bad node. ``field`` is
    the body's member they are sent as ("nodes" or "reference")."""
    where = _where(index, body_id)
    pointer = f"/bodies/{index}/{field}"
    try:
        arr = np.array(nodes, dtype=np.float64, order="C", copy=True)
    except (TypeError, ValueError) as exc:
        raise InvalidScene(f"{field} are not an (n, 2) array of numbers ({exc})", code="invalid_type",
                           pointer=pointer, where=where) from None
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise InvalidScene(f"{field} must have shape (n, 2), got {arr.shape}", code="invalid_type",
                           pointer=pointer, where=where)
    if arr.shape[0] == 0:
        raise InvalidScene("body has no nodes", code="no_nodes", pointer=pointer, where=where)
    bad = ~np.isfinite(arr).all(axis=1)
    if bad.any():
        j = int(np.flatnonzero(bad)[0])
        raise InvalidScene(f"coordinate is not a finite number: node {j} = {arr[j].tolist()}",
                           code="non_finite", pointer=f"{pointer}/{j}", where=f"{where}, node {j}")
    return arr


def _friction_option(value: Optional[Union[float, Mapping[str, Any]]]) -> Optional[Dict[str, float]]:
    """The scene's ``friction`` option (docs/model.md §14) as the service takes
    it, ``{"coefficient": mu[, "tangential_penalty": eps_T]}``, from a number
    (the coefficient) or such a mapping; checked as the service checks it."""
    if value is None:
        return None
    doc: Dict[str, Any] = {"coefficient": value} if not isinstance(value, Mapping) else dict(value)
    unknown = set(doc) - {"coefficient", "tangential_penalty"}
    if unknown:
        raise InvalidScene(f"unknown friction field {sorted(unknown)[0]!r}", code="unknown_field",
                           pointer=f"/options/friction/{sorted(unknown)[0]}")
    for name, lo, hi in (("coefficient", 0.0, 10.0), ("tangential_penalty", 0.0, math.inf)):
        if name not in doc:
            if name == "coefficient":
                raise InvalidScene("friction needs a coefficient", code="missing_field",
                                   pointer="/options/friction/coefficient")
            continue
        v = doc[name]
        if not is_number(v):
            raise InvalidScene(f"friction {name} must be a number", code="invalid_type",
                               pointer=f"/options/friction/{name}")
        if not (lo <= float(v) <= hi) or not math.isfinite(float(v)):
            raise InvalidScene(f"friction {name} {v!r} is out of range", code="invalid_option",
                               pointer=f"/options/friction/{name}")
        doc[name] = float(v)
    return doc


@dataclass
class Body:
    """One body: ``nodes`` ``(n, 2)`` float64, and ``loops`` or ``triangles`` (or neither).
    ``reference`` (``(n, 2)``, or None for the nodes themselves) is where the
    tributary lengths of ``penalty_scaling="length"`` are measured. ``surface``
    (``(m, 2)`` int64 node pairs, or None for the whole boundary) is the body's
    contact surface."""

    id: BodyId
    nodes: FloatArray
    loops: Optional[List[IntArray]] = None
    triangles: Optional[IntArray] = None
    alpha: Optional[float] = None
    role: Optional[str] = None
    mesh_points: Optional[IntArray] = None
    reference: Optional[FloatArray] = None
    surface: Optional[IntArray] = None
    friction: Optional[float] = None
    self_contact: bool = False

    @property
    def node_count(self) -> int:
        """How many nodes the body has (the rows of ``nodes``)."""
        return int(self.nodes.shape[0])

    def to_dict(self) -> Dict[str, Any]:
        """The body as an entry of a scene document's ``bodies``: ``id`` and ``nodes``,
        and each optional field only when it is set."""
        out: Dict[str, Any] = {"id": self.id, "nodes": self.nodes.tolist()}
        if self.loops is not None:
            out["loops"] = [loop.tolist() for loop in self.loops]
        if self.triangles is not None:
            out["triangles"] = self.triangles.tolist()
        if self.alpha is not None:
            out["alpha"] = float(self.alpha)
        if self.role is not None:
            out["role"] = self.role
        if self.mesh_points is not None:
            out["mesh_points"] = self.mesh_points.tolist()
        if self.reference is not None:
            out["reference"] = self.reference.tolist()
        if self.surface is not None:
            out["surface"] = self.surface.tolist()
        if self.friction is not None:
            out["friction"] = float(self.friction)
        if self.self_contact:
            out["self_contact"] = True
        return out


class Scene:
    """A contact scene: options and bodies.

    >>> s = Scene(penalty=100.0, alpha=0.2, search_radius=0.1)
    >>> s.add_body(np.array([[0, 0], [1, 0], [1, 1], [0, 1]]), id="a")
    'a'

    ``None`` for an option means "the service's default" and leaves it out of the
    JSON. ``periodic`` is ``(lx, ly)``. Options the client does not know are kept in
    ``extra_options`` and sent as they are.
    """

    def __init__(
        self,
        penalty: Optional[float] = None,
        *,
        alpha: Optional[float] = None,
        search_radius: Optional[float] = None,
        periodic: Optional[Tuple[float, float]] = None,
        solver: Optional[str] = None,
        outputs: Optional[Sequence[str]] = None,
        penalty_scaling: Optional[str] = None,
        surface_extension: Optional[float] = None,
        friction: Optional[Union[float, Mapping[str, Any]]] = None,
        extra_options: Optional[Mapping[str, Any]] = None,
    ) -> None:
        if penalty_scaling not in (None, "node", "length"):
            raise InvalidScene(f"penalty_scaling is 'node' or 'length', not {penalty_scaling!r}",
                               code="invalid_value", pointer="/options/penalty_scaling")
        for name, value in (("penalty", penalty), ("alpha", alpha), ("search_radius", search_radius)):
            if value is not None:
                option_number(value, f"/options/{name}")  # (options_dict reads them again: they may be set later)
        extension = None if surface_extension is None else option_number(surface_extension,
                                                                         "/options/surface_extension")
        if extension is not None and not (0.0 <= extension <= 0.5):
            raise InvalidScene(f"surface_extension {surface_extension!r} is not in [0, 0.5]", code="invalid_option",
                               pointer="/options/surface_extension")
        self.penalty_scaling = penalty_scaling
        self.surface_extension = extension
        self.friction = _friction_option(friction)
        self.penalty = penalty
        self.alpha = alpha
        self.search_radius = search_radius
        self.periodic = periodic
        self.solver = solver
        self.outputs = outputs
        self.extra_options: Dict[str, Any] = dict(extra_options or {})
        self._bodies: List[Body] = []
        self._index: Dict[Tuple[type, BodyId], int] = {}

    # ------------------------------------------------------------ options

    @property
    def periodic(self) -> Optional[Tuple[float, float]]:
        """The periodic box ``(lx, ly)``, or ``None`` for an open scene; set it from any
        pair of numbers."""
        return self._periodic

    @periodic.setter
    def periodic(self, value: Optional[Sequence[float]]) -> None:
        if value is None:
            self._periodic: Optional[Tuple[float, float]] = None
            return
        lx, ly = value
        self._periodic = (option_number(lx, "/options/periodic/lx"), option_number(ly, "/options/periodic/ly"))

    @property
    def outputs(self) -> Optional[List[str]]:
        """The outputs asked for (names of :data:`OUTPUTS`), or ``None`` for the service's
        default; set it from a list or a comma-separated string (an unknown name
        raises :class:`InvalidScene`)."""
        return self._outputs

    @outputs.setter
    def outputs(self, value: Optional[Union[str, Sequence[str]]]) -> None:
        self._outputs = normalize_outputs(value)

    def options_dict(self) -> Dict[str, Any]:
        """``options`` as sent: only the options that are set."""
        opts: Dict[str, Any] = {}
        for name in ("alpha", "penalty", "search_radius"):
            value = getattr(self, name)
            if value is not None:
                opts[name] = option_number(value, f"/options/{name}")
        if self.periodic is not None:
            opts["periodic"] = {"lx": self.periodic[0], "ly": self.periodic[1]}
        if self.solver is not None:
            opts["solver"] = self.solver
        if self.outputs is not None:
            opts["outputs"] = list(self.outputs)
        if self.penalty_scaling is not None:
            opts["penalty_scaling"] = self.penalty_scaling
        if self.surface_extension is not None:
            opts["surface_extension"] = self.surface_extension
        if self.friction is not None:
            opts["friction"] = dict(self.friction)
        opts.update(self.extra_options)
        return opts

    # ------------------------------------------------------------- bodies

    def add_body(
        self,
        nodes: ArrayLike,
        loops: Optional[LoopsLike] = None,
        triangles: Optional[ArrayLike] = None,
        id: Optional[BodyId] = None,  # noqa: A002 - the JSON field's name
        *,
        alpha: Optional[float] = None,
        role: Optional[str] = None,
        mesh_points: Optional[ArrayLike] = None,
        reference: Optional[ArrayLike] = None,
        surface: Optional[ArrayLike] = None,
        friction: Optional[float] = None,
        self_contact: bool = False,
    ) -> BodyId:
        """Add a body and return its id (the next free integer when ``id`` is None).

        ``alpha`` is this body's own smoothing (walls want 0); ``role`` is
        ``"both"`` (default), ``"master"`` (an obstacle: never a slave, two
        masters never interact) or ``"slave"`` (offers no surface).
        ``reference`` is the body's reference configuration (``(n, 2)``, one
        point per node): with ``penalty_scaling="length"`` the tributary
        lengths are measured there, not at ``nodes``; give the first positions
        when sending the scene again at new ones in a solver loop, so that the
        same positions always give the same answer (a session keeps its own).
        ``surface`` is the body's contact surface (a side set, docs/model.md
        §13): an ``(m, 2)`` array of node pairs, each a segment of the body's
        boundary in either direction, each once; only these segments are
        masters and only their nodes slaves. None (default): the whole
        boundary; empty: the body takes part in nothing. For a body given by
        loops (or neither), whether each pair is a boundary segment is checked
        here; for a triangle mesh the service checks it. ``friction`` is this
        body's own Coulomb coefficient (docs/model.md §14; a pair rubs with the
        smaller of its two bodies', each the body's own or the scene's).
        ``self_contact``: the body's nodes also meet its own surface
        (docs/model.md §16: folds, a ring that collapses, a hole that closes;
        never at rest).
        Checks shapes, finiteness and index ranges; raises :class:`InvalidScene`
        naming the body and the node at fault.
        """
        index = len(self._bodies)
        if id is None:
            id = index
            while (int, id) in self._index:
                id += 1
        if isinstance(id, np.integer):  # (np.bool_ is not one: refused, as a bool is)
            id = int(id)
        if isinstance(id, bool) or not isinstance(id, (str, int)):
            raise InvalidScene(f"body id must be a string or an integer, got {type(id).__name__}",
                               code="invalid_type", pointer=f"/bodies/{index}/id", where=f"body index {index}")
        if isinstance(id, int) and abs(id) >= 2 ** 53:
            raise InvalidScene(f"integer body id {id} is not below 2^53 in magnitude: it would not survive a JSON "
                               "number (use a string)", code="invalid_value", pointer=f"/bodies/{index}/id",
                               where=f"body index {index}")
        own_alpha = None if alpha is None else option_number(alpha, f"/bodies/{index}/alpha", f"body index {index}")
        if own_alpha is not None and not (0.0 <= own_alpha <= 0.5):
            raise InvalidScene(f"body alpha {alpha!r} is not in [0, 0.5]", code="invalid_option",
                               pointer=f"/bodies/{index}/alpha", where=f"body index {index}")
        if role not in (None, "both", "master", "slave"):
            raise InvalidScene(f"body role {role!r} is not both, master or slave", code="invalid_value",
                               pointer=f"/bodies/{index}/role", where=f"body index {index}")
        key = (type(id), id)
        if key in self._index:
            raise InvalidScene(f"duplicate body id {id!r} (also body index {self._index[key]})",
                               code="duplicate_id", pointer=f"/bodies/{index}/id", where=_where(index, id))
        arr = as_nodes(nodes, index, id)
        n = arr.shape[0]
        where = _where(index, id)
        if loops is not None and triangles is not None:
            raise InvalidScene("give loops or triangles, not both", code="invalid_argument",
                               pointer=f"/bodies/{index}", where=where)
        loop_list: Optional[List[IntArray]] = None
        if loops is not None:
            raw: List[Any] = list(loops) if not isinstance(loops, np.ndarray) or loops.ndim != 1 else [loops]
            if raw and np.ndim(raw[0]) == 0:  # a single flat loop
                raw = [raw]
            if not raw:
                raise InvalidScene("loops is empty", code="invalid_argument", pointer=f"/bodies/{index}/loops",
                                   where=where)
            loop_list = []
            for li, loop in enumerate(raw):
                ptr = f"/bodies/{index}/loops/{li}"
                arr_l = _as_index_array(loop, f"loop {li}", index, id, ptr, n)
                if arr_l.ndim != 1:
                    raise InvalidScene(f"loop {li} must be a flat list of node indices", code="invalid_type",
                                       pointer=ptr, where=where)
                if arr_l.shape[0] < 3:
                    raise InvalidScene(f"loop {li} has {arr_l.shape[0]} nodes, fewer than 3", code="loop_too_short",
                                       pointer=ptr, where=f"{where}, loop {li}")
                bad = (arr_l < 0) | (arr_l >= n)
                if bad.any():
                    p = int(np.flatnonzero(bad)[0])
                    raise InvalidScene(f"node index {int(arr_l[p])} out of range [0, {n})", code="index_out_of_range",
                                       pointer=f"{ptr}/{p}", where=f"{where}, loop {li}, position {p}")
                loop_list.append(arr_l)
        tri: Optional[IntArray] = None
        if triangles is not None:
            ptr = f"/bodies/{index}/triangles"
            tri = _as_index_array(triangles, "triangles", index, id, ptr, n)
            if tri.size == 0:
                tri = tri.reshape(0, 3)
            if tri.ndim != 2 or tri.shape[1] != 3:
                raise InvalidScene(f"triangles must have shape (m, 3), got {tri.shape}", code="invalid_type",
                                   pointer=ptr, where=where)
            if tri.shape[0] == 0:
                raise InvalidScene("triangles is empty", code="invalid_argument", pointer=ptr, where=where)
            bad = ((tri < 0) | (tri >= n)).any(axis=1)
            if bad.any():
                t = int(np.flatnonzero(bad)[0])
                raise InvalidScene(f"triangle {t} = {tri[t].tolist()} has a node index out of range [0, {n})",
                                   code="index_out_of_range", pointer=f"{ptr}/{t}", where=f"{where}, triangle {t}")
        elif loops is None and n < 3:
            raise InvalidScene(f"a body without loops or triangles needs 3 nodes or more, got {n}",
                               code="loop_too_short", pointer=f"/bodies/{index}/nodes", where=where)
        mp: Optional[IntArray] = None
        if mesh_points is not None:
            mp = _as_index_array(mesh_points, "mesh_points", index, id, f"/bodies/{index}/mesh_points")
            if mp.shape != (n,) or (mp < 0).any():
                raise InvalidScene(f"mesh_points needs one non-negative index per node ({n}), got shape {mp.shape}",
                                   code="invalid_value", pointer=f"/bodies/{index}/mesh_points", where=where)
        ref: Optional[FloatArray] = None
        if reference is not None:
            ref = as_nodes(reference, index, id, field="reference")
            if ref.shape != arr.shape:
                raise InvalidScene(f"reference has shape {ref.shape}, the nodes {arr.shape} (one point per node)",
                                   code="invalid_value", pointer=f"/bodies/{index}/reference", where=where)
        surf: Optional[IntArray] = None
        if surface is not None:
            surf = as_surface(surface, n, index, id)
            if tri is None:
                check_surface_segments(surf, loop_list if loop_list is not None else [np.arange(n)], n, index, id)
        if friction is not None and not (is_number(friction) and 0.0 <= float(friction) <= 10.0):
            raise InvalidScene(f"body friction {friction!r} is not a number in [0, 10]", code="invalid_option",
                               pointer=f"/bodies/{index}/friction", where=f"body index {index}")
        if not isinstance(self_contact, (bool, np.bool_)):
            raise InvalidScene(f"self_contact {self_contact!r} is not true or false", code="invalid_type",
                               pointer=f"/bodies/{index}/self_contact", where=f"body index {index}")
        self._bodies.append(Body(id=id, nodes=arr, loops=loop_list, triangles=tri,
                                 alpha=own_alpha, role=role, mesh_points=mp,
                                 reference=ref, surface=surf, friction=None if friction is None else float(friction),
                                 self_contact=bool(self_contact)))
        self._index[key] = index
        return id

    def set_nodes(self, id: BodyId, nodes: ArrayLike) -> None:  # noqa: A002
        """Move a body: new positions with the same shape (as in a solver's time step)."""
        index = self.index_of(id)
        arr = as_nodes(nodes, index, id)
        old = self._bodies[index].nodes
        if arr.shape != old.shape:
            raise InvalidScene(f"new nodes have shape {arr.shape}, the body has {old.shape}", code="invalid_type",
                               pointer=f"/bodies/{index}/nodes", where=_where(index, id))
        self._bodies[index].nodes = arr

    def positions(self) -> FloatArray:
        """Every node of every body, ``(N, 2)`` in global order (bodies in order)."""
        if not self._bodies:
            return np.zeros((0, 2), dtype=np.float64)
        return np.concatenate([b.nodes for b in self._bodies], axis=0)

    def set_positions(self, positions: ArrayLike) -> None:
        """Move every body at once: an ``(N, 2)`` array in global order (the layout
        of :meth:`positions`, of ``Result.force_array()`` and of sessions)."""
        arr = np.asarray(positions, dtype=np.float64)
        n = sum(b.node_count for b in self._bodies)
        if arr.shape != (n, 2):
            raise InvalidScene(f"positions of shape {arr.shape}, expected ({n}, 2)", code="invalid_value",
                               pointer="/positions")
        k = 0
        for b in self._bodies:
            self.set_nodes(b.id, arr[k:k + b.node_count])
            k += b.node_count

    def index_of(self, id: BodyId) -> int:  # noqa: A002
        """The position of the body ``id`` in the scene (the order of the answer);
        :class:`KeyError` when no body has that id."""
        try:
            return self._index[body_key(id)]
        except KeyError:
            raise KeyError(f"no body with id {id!r}") from None

    def body(self, id: BodyId) -> Body:  # noqa: A002
        """The :class:`Body` with this ``id``; :class:`KeyError` when there is none."""
        return self._bodies[self.index_of(id)]

    @property
    def bodies(self) -> List[Body]:
        """The bodies in scene order (a new list: changing it changes nothing)."""
        return list(self._bodies)

    @property
    def body_ids(self) -> List[BodyId]:
        """The bodies' ids in scene order."""
        return [b.id for b in self._bodies]

    def __len__(self) -> int:
        return len(self._bodies)

    def __iter__(self) -> Iterator[Body]:
        return iter(self._bodies)

    def __repr__(self) -> str:
        nodes = sum(b.node_count for b in self._bodies)
        return f"Scene(bodies={len(self._bodies)}, nodes={nodes}, options={self.options_dict()!r})"

    # ---------------------------------------------------------- checking

    def check(self, allow_empty: bool = False) -> None:
        """What the client checks before sending (beyond ``add_body``'s checks);
        ``allow_empty``: a part of a scene, which may hold no bodies."""
        if not self._bodies and not allow_empty:
            raise InvalidScene("scene has no bodies", code="empty_scene", pointer="/bodies")
        if self.penalty is None:
            raise InvalidScene("options.penalty is required", code="missing_field", pointer="/options/penalty")
        for name in ("alpha", "penalty", "search_radius"):
            v = getattr(self, name)
            if v is not None and not math.isfinite(float(v)):
                raise InvalidScene(f"option {name} is not finite", code="non_finite", pointer=f"/options/{name}")
        if self.periodic is not None:
            for k, v in zip(("lx", "ly"), self.periodic):
                if not math.isfinite(v):
                    raise InvalidScene(f"periodic.{k} is not finite", code="non_finite",
                                       pointer=f"/options/periodic/{k}")

    # ------------------------------------------------------------ (de)serialising

    def to_dict(self) -> Dict[str, Any]:
        """The scene document (``version``, ``options``, ``bodies``) as plain Python
        objects, ready for :func:`json.dumps`."""
        return {"version": 1, "options": self.options_dict(), "bodies": [b.to_dict() for b in self._bodies]}

    def to_json(self, indent: Optional[int] = None) -> str:
        """JSON text; every double is written so that it reads back bitwise equal."""
        doc = self.to_dict()
        try:
            return json.dumps(doc, indent=indent, allow_nan=False, separators=None if indent else (",", ":"),
                              default=_plain)
        except (ValueError, TypeError):
            dump_document(doc)  # raises InvalidScene at the value's pointer (json's bare error otherwise)
            raise

    @classmethod
    def from_dict(cls, doc: Mapping[str, Any]) -> "Scene":
        """A scene from a parsed scene document (``version`` 1). Options the client does
        not know go to ``extra_options``; a malformed document raises
        :class:`InvalidScene` with the code and JSON pointer the service would give."""
        if not isinstance(doc, Mapping):
            raise InvalidScene("a scene is a JSON object", code="invalid_type", pointer="")
        version = doc.get("version", 1)
        if version != 1:
            raise InvalidScene(f"unsupported scene version {version!r}", code="invalid_value",
                               pointer="/version")
        opts = dict(doc.get("options") or {})
        periodic = opts.pop("periodic", None)
        scene = cls(
            penalty=opts.pop("penalty", None),
            alpha=opts.pop("alpha", None),
            search_radius=opts.pop("search_radius", None),
            periodic=(periodic["lx"], periodic["ly"]) if isinstance(periodic, Mapping) else periodic,
            solver=opts.pop("solver", None),
            outputs=opts.pop("outputs", None),
            penalty_scaling=opts.pop("penalty_scaling", None),
            surface_extension=opts.pop("surface_extension", None),
            friction=opts.pop("friction", None),
            extra_options=opts,
        )
        bodies = doc.get("bodies")
        if not isinstance(bodies, list):
            raise InvalidScene("bodies must be a list", code="invalid_type", pointer="/bodies")
        for i, b in enumerate(bodies):
            if not isinstance(b, Mapping) or "nodes" not in b:
                raise InvalidScene("a body is an object with nodes", code="invalid_type", pointer=f"/bodies/{i}")
            scene.add_body(b["nodes"], loops=b.get("loops"), triangles=b.get("triangles"), id=b.get("id", i),
                           alpha=b.get("alpha"), role=b.get("role"), mesh_points=b.get("mesh_points"),
                           reference=b.get("reference"), surface=b.get("surface"), friction=b.get("friction"),
                           self_contact=b.get("self_contact", False))
        return scene

    @classmethod
    def from_json(cls, text: Union[str, bytes]) -> "Scene":
        """A scene from JSON text; invalid JSON (``NaN`` and ``Infinity`` included) raises
        :class:`InvalidScene` (``invalid_json``, ``non_finite``), as :meth:`from_dict` does
        for a malformed document."""
        return cls.from_dict(parse_json(text))

    @classmethod
    def load(cls, path: Union[str, "os.PathLike[str]"]) -> "Scene":
        """A scene from a JSON file (:meth:`from_json` of its bytes)."""
        with open(path, "rb") as fh:
            return cls.from_json(fh.read())

    def save(self, path: Union[str, "os.PathLike[str]"], indent: Optional[int] = None) -> None:
        """Write :meth:`to_json` (``indent`` as there) and a newline to ``path``."""
        with open(path, "w", encoding="utf-8") as fh:
            fh.write(self.to_json(indent=indent))
            fh.write("\n")


def parse_json(text: Union[str, bytes, bytearray]) -> Any:
    """JSON text read by the client (a scene given as text, to be sent with
    other fields or held in a session): text that is not JSON raises
    :class:`InvalidScene` ``invalid_json`` saying where (line, column, as the
    service says it), ``NaN`` and ``Infinity`` ``non_finite``."""
    def reject(name: str) -> float:
        raise InvalidScene(f"{name} is not a JSON number", code="non_finite", pointer="")

    try:
        return json.loads(text, parse_constant=reject)
    except json.JSONDecodeError as exc:
        raise InvalidScene(f"{exc.msg} at line {exc.lineno}, column {exc.colno}", code="invalid_json",
                           pointer="") from None
    except UnicodeDecodeError as exc:
        raise InvalidScene(f"not UTF-8: {exc.reason} at byte {exc.start}", code="invalid_json", pointer="") from None


def scene_document(text: Union[str, bytes, bytearray]) -> Dict[str, Any]:
    """A scene document from JSON text (:func:`parse_json`): anything but an
    object is the service's ``invalid_type`` at ``""``."""
    doc = parse_json(text)
    if not isinstance(doc, dict):
        raise InvalidScene(f"expected a scene (an object), got {json_kind(doc)}", code="invalid_type", pointer="")
    return doc


def dump_document(doc: Any) -> bytes:
    """A document as compact JSON text, numpy's arrays and scalars as the
    lists and numbers they hold. JSON has no NaN or infinity: the first one
    met (in the order written) is the service's ``non_finite`` at its
    pointer, and a value JSON cannot hold ``invalid_type`` at its own, where
    ``json.dumps`` would raise a bare ``ValueError`` or ``TypeError``."""
    try:
        return json.dumps(doc, allow_nan=False, separators=(",", ":"), default=_plain).encode("utf-8")
    except (ValueError, TypeError) as exc:
        found = _first_fault(doc, "", set())
        if found is None:
            raise
        pointer, why, code = found
        raise InvalidScene(why, code=code, pointer=pointer) from None


def _plain(value: Any) -> Any:
    """numpy's arrays and scalars as Python's lists and numbers, for json.dumps."""
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"{type(value).__name__} is not JSON")


def _type_name(value: Any) -> str:
    """A value's type as a user would look it up: ``tuple``, ``numpy.bool_``."""
    t = type(value)
    return t.__name__ if t.__module__ == "builtins" else f"{t.__module__}.{t.__name__}"


def _json_key(key: Any) -> Optional[str]:
    """The object key json.dumps writes for ``key`` (True as ``true``, 1.5 as
    ``1.5``), else None: a key it refuses (a tuple, a numpy integer, a NaN)."""
    if isinstance(key, str):
        return key
    if key is None or isinstance(key, bool):
        return json.dumps(key)
    if isinstance(key, int):
        return int.__repr__(key)
    if isinstance(key, float):
        return float.__repr__(key) if math.isfinite(key) else None
    return None


_FINITE = "not a finite number (JSON has no NaN or infinity)"


def _first_fault(value: Any, pointer: str, open_: Set[int]) -> Optional[Tuple[str, str, str]]:
    """Where json.dumps (``allow_nan=False``, numpy's values as ``_plain``
    gives them) first fails in ``value``, in the order it writes: the JSON
    pointer, the message and the service's code (``non_finite`` for a NaN or
    an infinity, ``invalid_type`` for what JSON cannot hold: a key it
    refuses, at its object; another type; a container that holds itself,
    ``open_`` the containers around this one); None where it would not."""
    if isinstance(value, (np.ndarray, np.generic)):
        value = _plain(value)
    if isinstance(value, float):
        return None if math.isfinite(value) else (pointer, _FINITE, "non_finite")
    if value is None or isinstance(value, (bool, int, str)):
        return None
    if not isinstance(value, (dict, list, tuple)):  # (a Mapping that is no dict included: json.dumps refuses it)
        return pointer, f"expected a JSON value, got {_type_name(value)}", "invalid_type"
    if id(value) in open_:
        return pointer, "a value that holds itself (JSON has no references)", "invalid_type"
    open_.add(id(value))
    try:
        for key, item in (value.items() if isinstance(value, dict) else enumerate(value)):
            name = _json_key(key) if isinstance(value, dict) else str(key)
            if name is None:
                bad = isinstance(key, float)
                return (pointer, f"an object's key is {_FINITE}" if bad else
                        f"an object's keys are strings, got {_type_name(key)}", "non_finite" if bad else "invalid_type")
            found = _first_fault(item, f"{pointer}/{name.replace('~', '~0').replace('/', '~1')}", open_)
            if found is not None:
                return found
        return None
    finally:
        open_.discard(id(value))


def json_kind(value: Any) -> str:
    """What ``value`` is, in the service's words for a JSON value ("an
    array", "a number"), else its Python type's name."""
    if isinstance(value, (bool, np.bool_)):
        return "a boolean"
    if isinstance(value, (int, float, np.integer, np.floating)):
        return "a number"
    if isinstance(value, str):
        return "a string"
    if isinstance(value, Mapping):
        return "an object"
    if isinstance(value, (list, tuple)):
        return "an array"
    return "null" if value is None else type(value).__name__


def normalize_outputs(value: Optional[Union[str, Sequence[str]]]) -> Optional[List[str]]:
    """``"forces,energy"`` or ``["forces", "energy"]`` to a checked list (None stays None)."""
    if value is None:
        return None
    items = [v.strip() for v in value.split(",")] if isinstance(value, str) else [str(v) for v in value]
    items = [v for v in items if v]
    unknown = [v for v in items if v not in OUTPUTS]
    if unknown:
        raise InvalidScene(f"unknown output {unknown[0]!r} (known: {', '.join(OUTPUTS)})", code="invalid_option",
                           pointer="/options/outputs")
    return items


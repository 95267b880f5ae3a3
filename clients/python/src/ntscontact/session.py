"""Scene sessions: the topology sent once, then positions at every step.

>>> with client.session(scene) as s:                         # doctest: +SKIP
...     for step in range(1000):
...         r = s.contact(x)                                  # x: (N, 2) float64, global order
...         f = r.force_array()                               # (N, 2), no per-node Python work

The positions travel as raw little-endian float64 (16 N bytes) and, when only
forces, energy and virial are asked for, the forces come back the same way
(``np.frombuffer``), with the summary in the ``NTS-*`` headers. Contacts or
gaps need the JSON answer; the positions are still sent raw. Global order is
bodies in the scene's order, nodes in each body's order.

With ``exchange="surface"`` a binary step sends the positions of the
surface nodes alone (the nodes on the scene's loops, :attr:`Session.surface`)
and receives their forces alone: a mesh's interior nodes, which contact
neither reads nor pushes, do not travel. The results are the same, bit for
bit; :meth:`Result.force_array` still has every node (zeros inside).

If the service no longer knows the session (it expired or was evicted, the
daemon restarted, or a load balancer sent the step to another daemon), the
session is created again from the scene it holds and the step retried once.
"""

from __future__ import annotations

import json
import math
import re
import threading
import warnings as _warnings
from typing import TYPE_CHECKING, Any, Callable, Dict, Iterator, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

from .errors import InvalidScene, NtsError, ServerError
from .result import IncompleteResultWarning, Result, ResultWarning, Summary, user_stacklevel, virial_matrix
from .scene import BodyId, Scene, body_key, dump_document, normalize_outputs, option_number, scene_document

if TYPE_CHECKING:
    from .client import Answer

__all__ = ["Session", "PositionsLike"]

FloatArray = npt.NDArray[np.float64]
PositionsLike = Union[npt.ArrayLike, Mapping[BodyId, npt.ArrayLike]]

#: Outputs a binary answer carries (the forces, and the summary in headers).
_BINARY_OUTPUTS = frozenset(("forces", "energy", "virial", "stiffness", "pressure"))
_OCTET = "application/octet-stream"


def non_finite_rows(arr: FloatArray) -> npt.NDArray[np.int64]:
    """The rows of ``arr`` with a NaN or an infinity, ascending (none: empty;
    the common case pays one pass)."""
    if np.isfinite(arr).all():
        return np.zeros(0, dtype=np.int64)
    return np.flatnonzero(~np.isfinite(arr).all(axis=1)).astype(np.int64)


def non_finite_error(k: int, body: int, node: int, row: FloatArray) -> InvalidScene:
    """The service's own error for positions whose first row with a NaN or an
    infinity is ``k`` (``row``), node ``node`` of body ``body``: its code,
    pointer and words."""
    what = "y" if np.isfinite(row[0]) else "x"
    return InvalidScene(f"position {k} (/bodies/{body}/nodes/{node}) has a non-finite {what}", code="non_finite",
                        pointer=f"/positions/{k}")


def _to_callers_row(exc: NtsError, surface: npt.NDArray[np.int64]) -> None:
    """An error of a step that sent the surface rows alone: its pointer
    ``/positions/K`` (the K-th row sent) made the caller's row,
    ``/positions/<surface[K]>``, as docs/python.md says it is."""
    m = re.fullmatch(r"/positions/(\d+)", exc.pointer)
    if m and int(m.group(1)) < len(surface):
        exc.pointer = f"/positions/{surface[int(m.group(1))]}"
        exc.args = (exc._render(),)


class BodyArrays(Mapping[BodyId, FloatArray]):
    """A binary answer's per-body arrays, ``{body_id: view}`` in scene order: each
    body's view of the one array is cut when asked for (a dict of them all cost
    a millisecond per step at 1,024 bodies)."""

    def __init__(self, whole: FloatArray, offsets: Sequence[int], ids: Sequence[BodyId],
                 index: Mapping[Tuple[type, BodyId], int]) -> None:
        self._whole, self._offsets, self._ids, self._index = whole, offsets, ids, index

    def __getitem__(self, body_id: BodyId) -> FloatArray:
        k = self._index[body_key(body_id)]
        return self._whole[self._offsets[k]:self._offsets[k + 1]]

    def __iter__(self) -> Iterator[BodyId]:
        return iter(self._ids)

    def __len__(self) -> int:
        return len(self._ids)

    def __repr__(self) -> str:
        return f"BodyArrays({len(self._ids)} bodies)"


def _rows(body: Any, k: int) -> FloatArray:
    """Body k's nodes as float64 rows [x, y] (the client keeps the stored
    positions); nodes of another shape, or a body that is not an object,
    are the service's invalid_type, named where they are."""
    if not isinstance(body, Mapping):
        raise InvalidScene(f"expected a body (an object), got {type(body).__name__}", code="invalid_type",
                           pointer=f"/bodies/{k}")
    nodes = body.get("nodes")
    if nodes is None or (isinstance(nodes, (list, tuple)) and not nodes):
        return np.zeros((0, 2))  # (none: the service says what a body needs)
    try:
        rows = np.asarray(nodes, dtype=np.float64)
        if rows.ndim != 2 or rows.shape[1] != 2:
            raise ValueError(f"shape {rows.shape}")
    except (TypeError, ValueError) as exc:
        raise InvalidScene(f"expected an array of [x, y] nodes ({exc})", code="invalid_type",
                           pointer=f"/bodies/{k}/nodes") from exc
    return rows


class Session:
    """A scene held by the service (``POST /v1/scenes``); see the module's doc.

    Made by :meth:`Client.session`. ``id`` is the service's id, ``nodes`` the
    number N of positions a step takes, ``body_ids`` and ``node_counts`` the
    layout of the global order. ``recreated`` counts the times the session had
    to be created again (after a 404 ``unknown_scene``).
    """

    #: A session holds a whole scene: no bodies is an ``empty_scene``. A
    #: rank's part of a distributed one (``ntscontact.mpi``) may hold none.
    _may_hold_no_bodies = False

    def __init__(self, client: Any, scene: Union[Scene, Mapping[str, Any], str, bytes], *,
                 timeout: Optional[Any] = None, keep_contacts: bool = False, keep_candidates: bool = True,
                 skin: Optional[float] = None, exchange: str = "all") -> None:
        if exchange not in ("all", "surface"):
            raise ValueError(f"exchange must be 'all' or 'surface', not {exchange!r}")
        self.client = client
        self.exchange = exchange
        self.timeout = timeout
        if isinstance(scene, Scene):
            scene.check(allow_empty=self._may_hold_no_bodies)
            doc: Dict[str, Any] = scene.to_dict()
        elif isinstance(scene, Mapping):
            doc = dict(scene)
        elif isinstance(scene, (str, bytes, bytearray)):
            doc = scene_document(scene)
        else:
            raise TypeError(f"scene must be a Scene, a mapping or JSON text, not {type(scene).__name__}")
        if keep_contacts:  # each step's contacts matched to the last's (docs/sessions.md)
            doc["session"] = {**(doc.get("session") or {}), "keep_contacts": True}
        if not keep_candidates:  # the kept candidate list: time only, never the answer
            doc["session"] = {**(doc.get("session") or {}), "keep_candidates": False}
        if skin is not None:
            length = option_number(skin, "/session/skin")
            if not math.isfinite(length):  # (the service's words: JSON has no NaN to send it)
                raise InvalidScene("the skin is a length >= 0 (absent: 0.3 times the search radius)",
                                   code="invalid_option", pointer="/session/skin")
            doc["session"] = {**(doc.get("session") or {}), "skin": length}
        bodies = doc.get("bodies")
        if not isinstance(bodies, list) or (not bodies and not self._may_hold_no_bodies):
            raise InvalidScene("scene has no bodies", code="empty_scene", pointer="/bodies")
        self._body = dump_document(doc)
        rows = [_rows(b, k) for k, b in enumerate(bodies)]
        self.body_ids: List[BodyId] = [b.get("id") for b in bodies]
        self.node_counts: List[int] = [len(r) for r in rows]
        self._offsets = np.concatenate([[0], np.cumsum(self.node_counts)]).astype(np.int64)
        self._index = {(type(i), i): k for k, i in enumerate(self.body_ids)}
        options = doc.get("options") if isinstance(doc.get("options"), Mapping) else {}
        self._scene_outputs = frozenset(options.get("outputs", ("forces", "energy", "virial")))
        # Friction keeps a history in the session (docs/model.md §14): a
        # session the service lost and the client re-creates starts it anew.
        self._friction = bool(options.get("friction")) or any(
            isinstance(b, Mapping) and b.get("friction") for b in bodies)
        self.nodes = int(self._offsets[-1])
        # The client's copy of the stored positions: what a re-created session
        # must be sent to go on where the lost one was.
        self._positions: FloatArray = np.concatenate([np.zeros((0, 2))] + rows)
        # A surface exchange's last rows sent, not yet set into _positions
        # (_stored: only when every node's positions are asked for). The two
        # change together, under _held_lock (steps may run on several threads).
        self._rows: Optional[FloatArray] = None
        self._held_lock = threading.Lock()
        # Held for a whole step, the call and the update of the stored
        # positions: another thread's step, accepted after this one, must not
        # have its positions replaced by this one's (steps one at a time).
        self._stepping = threading.Lock()
        self._history_lost = False  # (a re-creation lost the friction history: said after the step)
        self.id = ""
        self.surface_nodes = 0
        #: With ``exchange="surface"``: the surface nodes' global indices,
        #: ascending (``GET /v1/scenes/{id}/surface``), the rows a step sends.
        self.surface: Optional[npt.NDArray[np.int64]] = None
        self.recreated = 0
        self.steps = 0
        self._closed = False
        self._create()

    # ------------------------------------------------------------ lifecycle

    def _create(self) -> None:
        doc, _ = self._request("POST", "/v1/scenes", data=self._body, headers={"Content-Type": "application/json"})
        self.id = str(doc["id"])
        self.surface_nodes = int(doc.get("surface_nodes", 0))
        if int(doc.get("nodes", -1)) != self.nodes:
            raise ServerError(f"the service counts {doc.get('nodes')} nodes, the scene has {self.nodes}",
                              code="bad_response")
        if self.exchange == "surface":
            self.surface = self._check_surface(self._surface_nodes())

    def _surface_nodes(self) -> Sequence[int]:
        doc, _ = self._request("GET", f"/v1/scenes/{self.id}/surface")
        return list(doc.get("nodes") or [])

    def _check_surface(self, nodes: Sequence[int]) -> npt.NDArray[np.int64]:
        idx = np.asarray(nodes, dtype=np.int64)
        if idx.ndim != 1 or len(idx) == 0 or idx[0] < 0 or idx[-1] >= self.nodes or np.any(np.diff(idx) <= 0):
            raise ServerError("the service's surface nodes are not ascending node indices", code="bad_response")
        return idx

    def close(self) -> None:
        """``DELETE /v1/scenes/{id}`` (a session the service no longer has is fine)."""
        if self._closed:
            return
        self._closed = True
        try:
            self._request("DELETE", f"/v1/scenes/{self.id}", expect_json=False)
        except NtsError as exc:
            if exc.status != 404:
                raise

    def __enter__(self) -> "Session":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"Session(id={self.id!r}, nodes={self.nodes}, steps={self.steps}, recreated={self.recreated})"

    def info(self) -> Dict[str, Any]:
        """``GET /v1/scenes/{id}``: nodes, steps, memory, time to expiry (not a use)."""
        doc, _ = self._request("GET", f"/v1/scenes/{self.id}")
        return doc

    # ------------------------------------------------------------ positions

    def positions(self) -> FloatArray:
        """A copy of the stored positions, (N, 2) in global order (with
        ``exchange="surface"``: the surface nodes' as last sent, the others'
        as last sent with every node, as the service holds them)."""
        return self._stored().copy()

    def _stored(self) -> FloatArray:
        with self._held_lock:
            if self._rows is not None and self.surface is not None:
                whole = self._positions.copy()  # (never written in place: results share it)
                whole[self.surface] = self._rows
                self._positions, self._rows = whole, None
            return self._positions

    def _as_positions(self, positions: PositionsLike) -> FloatArray:
        if isinstance(positions, Mapping):
            out = self._stored().copy()
            for body_id, value in positions.items():
                k = self._index.get(body_key(body_id), -1)
                if k < 0:
                    raise InvalidScene(f"positions for body id {body_id!r}: the session has no body with that id",
                                       code="invalid_value", pointer="/positions")
                arr = np.asarray(value, dtype=np.float64)
                want = (self.node_counts[k], 2)
                if arr.shape != want:
                    raise InvalidScene(f"body {body_id!r}: positions of shape {arr.shape}, expected {want}",
                                       code="invalid_value", pointer=f"/bodies/{k}/nodes")
                out[self._offsets[k]:self._offsets[k + 1]] = arr
            arr = out
        else:
            arr = np.asarray(positions, dtype=np.float64)
            if arr.shape != (self.nodes, 2):
                raise InvalidScene(f"positions of shape {arr.shape}, expected ({self.nodes}, 2): every node, "
                                   "bodies in scene order, nodes in body order", code="invalid_value",
                                   pointer="/positions")
        # Not read here for non-finite values: the service (the daemon, or the
        # in-process engine: the same codec) reads every position and refuses
        # those with this code, pointer and words (non_finite_error's), and a second
        # pass here cost a quarter of a step's wall time at 66k nodes
        # (docs/benchmarks.md). The distributed engine's library names the
        # body's node instead: ntscontact.mpi checks them first.
        return np.ascontiguousarray(arr, dtype="<f8")

    # ------------------------------------------------------------ steps

    def contact(
        self,
        positions: Optional[PositionsLike] = None,
        *,
        outputs: Optional[Union[str, Sequence[str]]] = None,
        penalty: Optional[float] = None,
        alpha: Optional[float] = None,
        search_radius: Optional[float] = None,
        solver: Optional[str] = None,
        commit: bool = True,
        timeout: Optional[Any] = None,
    ) -> Result:
        """One step at ``positions`` ((N, 2) in global order, or ``{body_id:
        (n_b, 2)}`` for the bodies that moved), or at the stored positions when
        None. The options override the scene's for this step only.
        ``commit`` (friction, docs/model.md §14): whether this step's anchors
        become the session's history; an implicit solver iterates Newton with
        ``commit=False`` and commits the converged step, an explicit one
        commits every step (the default)."""
        if self._closed:
            raise NtsError("the session is closed", code="closed")
        pos = self._as_positions(positions) if positions is not None else None
        outs = normalize_outputs(outputs)
        params: Dict[str, str] = {}
        if outs is not None:
            params["outputs"] = ",".join(outs)
        for name, value in (("penalty", penalty), ("alpha", alpha), ("search_radius", search_radius)):
            if value is not None:
                params[name] = repr(option_number(value, f"/options/{name}"))
        if solver is not None:
            params["solver"] = str(solver)
        if not commit:
            params["commit"] = "false"
        # The binary answer when everything asked for fits in it (the forces
        # and the summary): the step's outputs, else the scene's.
        wanted = set(outs) if outs is not None else set(self._scene_outputs)
        binary = wanted <= _BINARY_OUTPUTS
        # The surface nodes alone travel when the answer is binary (contacts
        # and gaps come in JSON, which carries every node).
        surface = binary and self.surface is not None
        if surface:
            params["nodes"] = "surface"
        # This step's own copy (the caller may move its array on), made while
        # the service computes: the step sends the caller's array. A surface
        # exchange's copy is the rows it sends.
        copies: List[FloatArray] = []
        rows = np.take(pos, self.surface, axis=0) if surface and pos is not None else None

        def keep_copy() -> None:
            if pos is not None and rows is None and not copies:
                copies.append(pos.astype("<f8", copy=True))

        stored: Any
        with self._stepping:
            try:
                doc, headers, content = self._post_step(rows if rows is not None else pos, params, binary, timeout,
                                                        keep_copy, surface)
            except NtsError as exc:
                if params.get("nodes") == "surface" and self.surface is not None:
                    _to_callers_row(exc, self.surface)
                raise
            # (a session created again answers its first step with every node: _post_step drops "nodes")
            surface = surface and params.get("nodes") == "surface"
            keep_copy()  # (a path that did not call it)
            if rows is not None:
                with self._held_lock:  # (the rows replace those of the step before: the same nodes)
                    base, idx, self._rows = self._positions, self.surface, rows

                def made() -> FloatArray:  # the stored positions after this step, made if asked (to_vtk, plot)
                    whole = base.copy()
                    whole[idx] = rows
                    return whole
                stored = made
            else:
                stored = copies[0] if pos is not None else self._stored()
                if pos is not None:
                    with self._held_lock:
                        self._positions, self._rows = stored, None
            self.steps += 1
            lost, self._history_lost = self._history_lost, False
        if lost:
            _warnings.warn(f"session {self.id}: the service lost it and the client created it anew: "
                           "its friction history is lost (every contact starts sticking where it is)",
                           IncompleteResultWarning, stacklevel=user_stacklevel())
        result = (self._binary_result(headers, content, "stiffness" in wanted, "pressure" in wanted, surface)
                  if binary else Result.from_dict(doc))
        # the stored positions are replaced, never written in place: shared, not copied
        result._scene = (self._scene_factory, stored)
        return result.warn()

    def _post_step(self, pos: Optional[FloatArray], params: Dict[str, str], binary: bool,
                   timeout: Optional[Any], while_waiting: Optional[Callable[[], None]] = None,
                   surface: bool = False) -> Tuple[Dict[str, Any], Mapping[str, str], Any]:
        """``POST /v1/scenes/{id}/contact``: the JSON answer, or the binary
        answer's headers and bytes; ``while_waiting`` called while the
        service computes (or before); ``surface``: ``pos`` holds the surface
        nodes' rows alone (``?nodes=surface``)."""
        headers = {"Content-Type": _OCTET}
        if binary:
            headers["Accept"] = _OCTET
        # A lost session is created again and the step repeated; twice at most,
        # for a session re-created while its daemon was away (behind a proxy
        # that routes by id) can be lost again when that daemon returns.
        for attempt in range(3):
            # After a re-creation the new session holds the scene's first
            # positions: send ours explicitly.
            send = pos if pos is not None else (self._stored() if attempt else None)
            if surface and attempt and self.surface is not None:
                # A session created anew holds the scene's first positions:
                # this step sends every node (the stored ones, this step's
                # surface rows), so that it holds what the client does.
                whole = self._stored().copy()
                if pos is not None:
                    whole[self.surface] = pos
                send = whole
                params.pop("nodes", None)
            elif surface and pos is None and send is not None and self.surface is not None:
                send = np.take(send, self.surface, axis=0)  # 16 S bytes
            # (sent from the array's own memory: no copy of 16 N bytes)
            data = memoryview(send).cast("B") if send is not None else b""
            try:
                doc, resp = self._request("POST", f"/v1/scenes/{self.id}/contact", data=data, headers=headers,
                                          params=params, timeout=timeout, expect_json=not binary,
                                          while_waiting=while_waiting)
                return doc, resp.headers, resp.content
            except NtsError as exc:
                if attempt < 2 and exc.status == 404 and exc.code == "unknown_scene":
                    self._create()
                    self.recreated += 1
                    # said once the step is done, outside the lock (a warning
                    # raised as an error here would leave the step half made)
                    self._history_lost = self._history_lost or self._friction
                    continue
                raise
        raise AssertionError("unreachable")  # the third attempt returns or raises

    def step(self, positions: Optional[PositionsLike] = None, *, commit: bool = True, **kw: Any) -> Result:
        """A solver's step: :meth:`contact` with ``commit`` (friction's history)."""
        return self.contact(positions, commit=commit, **kw)

    def _scene_factory(self) -> Scene:
        return Scene.from_json(self._body)

    def _binary_result(self, h: Mapping[str, str], body: Any, stiffness: bool, pressure: bool = False,
                       surface: bool = False) -> Result:
        """A binary answer read: ``body`` the bytes (any buffer: the daemon's
        answer, or the in-process engine's memory, viewed without a copy), ``h``
        the summary headers; ``surface``: the forces and pressures are the
        surface nodes' (:attr:`surface`), set into arrays of every node."""
        count = int(h.get("NTS-Stiffness-Triplets", 0) or 0)
        rows = len(self.surface) if surface and self.surface is not None else self.nodes
        size = 16 * rows + 16 * count + (8 * rows if pressure else 0)
        if len(body) != size:
            raise ServerError(f"a binary answer of {len(body)} bytes, expected {size}",
                              code="bad_response", status=200)
        # Views of the answer's own buffer, read-only (the wire reads it into a bytearray)
        body = memoryview(body).toreadonly()
        forces = np.frombuffer(body, dtype="<f8", count=2 * rows).reshape(rows, 2)
        if rows != self.nodes:
            every = np.zeros((self.nodes, 2), dtype="<f8")
            # (rows of 16 bytes set at once: half the time of a 2-D scatter)
            every.view("<c16").reshape(-1)[self.surface] = forces.view("<c16").reshape(-1)
            every.flags.writeable = False  # as the views of a whole answer are
            forces = every
        triplets = None
        if stiffness and not count:
            # Asked for, and no contact active: the empty 2N x 2N tangent, as
            # the JSON answers give it (not "no stiffness").
            empty = np.zeros(0, dtype=np.int64)
            triplets = (empty, empty, np.zeros(0, dtype=np.float64), 2 * self.nodes)
        elif count:
            off = 16 * rows
            trows = np.frombuffer(body, dtype="<i4", count=count, offset=off)
            tcols = np.frombuffer(body, dtype="<i4", count=count, offset=off + 4 * count)
            values = np.frombuffer(body, dtype="<f8", count=count, offset=off + 8 * count)
            triplets = (trows, tcols, values, 2 * self.nodes)
        try:
            virial = [float(v) for v in h["NTS-Virial"].split(",")]
            vd = {"xx": virial[0], "yy": virial[1], "xy": virial[2]}
            if len(virial) > 3:  # friction: yx (docs/model.md (28))
                vd["yx"] = virial[3]
            summary = Summary(
                bodies=len(self.body_ids), nodes=self.nodes, surface_nodes=self.surface_nodes,
                contacts=int(h["NTS-Contacts"]), gaps=int(h.get("NTS-Gaps", 0)), energy=float(h["NTS-Energy"]),
                virial=virial_matrix(vd),
                max_penetration=float(h["NTS-Max-Penetration"]),
                loops_reversed=int(h.get("NTS-Loops-Reversed", 0)),
                search_radius=float(h.get("NTS-Search-Radius", 0.0)), cell_size=float(h.get("NTS-Cell-Size", 0.0)),
                elapsed_ms=float(h.get("NTS-Elapsed-Ms", 0.0)), deep_contacts=int(h.get("NTS-Deep-Contacts", 0)),
                dissipation=float(h.get("NTS-Dissipation", 0.0)), sticking=int(h.get("NTS-Sticking", 0)),
                slipping=int(h.get("NTS-Slipping", 0)), friction="NTS-Dissipation" in h)
            warned = ResultWarning.from_header(h.get("NTS-Warnings", ""))
        except (KeyError, ValueError, IndexError) as exc:
            raise ServerError(f"a binary answer without a readable summary ({exc})", code="bad_response",
                              status=200) from exc
        per_body = BodyArrays(forces, self._offsets, self.body_ids, self._index)
        per_body_p: Mapping[BodyId, FloatArray] = {}
        if pressure:  # after the forces and the tangent
            p = np.frombuffer(body, dtype="<f8", count=rows, offset=16 * rows + 16 * count)
            if rows != self.nodes:
                every_p = np.zeros(self.nodes, dtype="<f8")
                every_p[self.surface] = p
                every_p.flags.writeable = False
                p = every_p
            per_body_p = BodyArrays(p, self._offsets, self.body_ids, self._index)
        return Result(summary=summary, forces=per_body, contacts=[], gaps=[], raw={}, warnings=warned,
                      _force_array=forces, _triplets=triplets, pressure=per_body_p)

    # ------------------------------------------------------------ HTTP

    def _request(self, method: str, path: str, *, data: Optional[Union[bytes, memoryview]] = None,
                 headers: Optional[Dict[str, str]] = None, params: Optional[Dict[str, str]] = None,
                 timeout: Optional[Any] = None, expect_json: bool = True,
                 while_waiting: Optional[Callable[[], None]] = None) -> Tuple[Dict[str, Any], Answer]:
        c = self.client
        t = timeout if timeout is not None else (self.timeout if self.timeout is not None else c.timeout)
        return c._call(method, path, body=data, headers=headers, params=params, timeout=t, body_ids=self.body_ids,
                       expect_json=expect_json, empty_ok=True, while_waiting=while_waiting)

"""One scene across MPI ranks, from Python (docs/distributed.md).

>>> from mpi4py import MPI                                  # doctest: +SKIP
>>> import ntscontact.mpi
>>> engine = ntscontact.mpi.DistributedEngine(MPI.COMM_WORLD)
>>> with engine.session(my_part, ids=my_global_indices) as s:
...     result = s.step(my_positions)       # every rank, together
...     result.energy, result.force_array()  # the whole's energy, my nodes' forces

Each rank holds a :class:`DistributedSession` of the bodies it owns (its part
of the scene, with the same ``options`` on every rank) and their global
indices (by default the bodies' integer ``id``). Every call is collective: all
ranks step together, each with the positions of its own nodes, and each gets a
:class:`~ntscontact.Result` whose summary (energy, virial, counts, warnings) is
the whole scene's and whose forces are its own nodes'. The answer is the same
bits as one process evaluating the whole scene (``ntscontact.Engine``), for
any number of ranks. An error is every rank's: the same exception, code and
message, its pointer naming the body by its global index.

The sessions give forces, energy and virial; contacts, gaps, the tangent and
the pressure of a distributed scene come from the C API (``ntsm_gather``) or
``ntscontact-mpi``. Friction's history is not distributed yet.

It needs mpi4py (``pip install 'ntscontact[mpi]'``) and
``libntscontact_mpi_engine.so`` (CMake ``-DNTS_MPI=ON``), found in
``$NTSCONTACT_MPI_LIBRARY`` or in the package.
"""

from __future__ import annotations

import ctypes
import dataclasses
import json
import os
from pathlib import Path
from typing import Any, Callable, Dict, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

from .engine import EngineUnavailable, locate
from .errors import InvalidScene, NtsError, error_from_response
from .result import Result
from .scene import Scene, is_integer
from .session import FloatArray, PositionsLike, Session, non_finite_error, non_finite_rows

__all__ = ["DistributedEngine", "DistributedSession", "LIBRARY_NAME", "find_library"]

#: The shared library's file name (CMake's ``ntscontact_mpi_engine`` target, with ``-DNTS_MPI=ON``).
LIBRARY_NAME = "libntscontact_mpi_engine.so"

#: The outputs' flags (the core's NTS_OUTPUT_MAP, tables.h).
_OUTPUT_BITS = {"forces": 1, "energy": 2, "virial": 4, "contacts": 8, "gaps": 16, "stiffness": 32, "pressure": 64}
_SOLVERS = {"closed_form": 0, "newton": 1}


def find_library() -> Path:
    """``$NTSCONTACT_MPI_LIBRARY``, else the copy bundled in the package."""
    found = locate("NTSCONTACT_MPI_LIBRARY", LIBRARY_NAME)
    if found is not None:
        return found
    raise EngineUnavailable(
        f"ntscontact.mpi needs {LIBRARY_NAME}: build it (`cmake -S . -B build -DNTS_MPI=ON && cmake --build "
        f"build`, with Open MPI: apt-get install libopenmpi-dev openmpi-bin) and set "
        f"NTSCONTACT_MPI_LIBRARY=build/lib/{LIBRARY_NAME}", code="engine_unavailable")


def _load(path: Path) -> ctypes.CDLL:
    try:
        lib = ctypes.CDLL(str(path), mode=ctypes.RTLD_GLOBAL)
    except OSError as exc:
        raise EngineUnavailable(f"cannot load {path}: {exc}", code="engine_unavailable") from exc
    vp, cp, sz, i, d = ctypes.c_void_p, ctypes.c_char_p, ctypes.c_size_t, ctypes.c_int, ctypes.c_double
    pcp = ctypes.POINTER(ctypes.c_void_p)
    sigs: Dict[str, Tuple[Any, List[Any]]] = {
        "ntsm_engine_create": (vp, [i, cp, sz, ctypes.POINTER(ctypes.c_int), i, i, pcp]),
        "ntsm_engine_counts": (None, [vp, ctypes.POINTER(ctypes.c_longlong)]),
        "ntsm_engine_step": (i, [vp, vp, sz, i, d, i, d, i, d, i, ctypes.c_uint, vp, pcp, pcp]),
        "ntsm_engine_free_text": (None, [vp]),
        "ntsm_engine_destroy": (None, [vp]),
    }
    try:
        for name, (res, args) in sigs.items():
            fn = getattr(lib, name)
            fn.restype, fn.argtypes = res, args
    except AttributeError as exc:
        raise EngineUnavailable(f"{path} is not ntscontact's MPI library ({exc})", code="engine_unavailable") from exc
    return lib


def _text(lib: ctypes.CDLL, ptr: ctypes.c_void_p) -> str:
    """The library's text, freed."""
    if not ptr.value:
        return ""
    try:
        return ctypes.string_at(ptr.value).decode("utf-8", "replace")
    finally:
        lib.ntsm_engine_free_text(ptr.value)


def _raise_document(raw: str) -> None:
    try:
        doc = json.loads(raw)
    except ValueError:
        doc = None
    code = doc.get("error", {}).get("code", "") if isinstance(doc, Mapping) else ""
    status = 500 if code in ("out_of_memory", "internal_error") else 400
    raise error_from_response(status, doc, raw)


class DistributedEngine:
    """The distributed evaluation over an mpi4py communicator (see the module's doc)."""

    def __init__(self, comm: Any = None, threads: int = 0, *,
                 library: Optional[Union[str, os.PathLike]] = None) -> None:
        from mpi4py import MPI  # the optional extra: imported where it is needed

        self.comm = comm if comm is not None else MPI.COMM_WORLD
        if not is_integer(threads) or not 0 <= threads <= 1024:
            raise ValueError(f"threads must be an integer in [0, 1024], not {threads!r}")
        self.threads = int(threads)
        self._lib = _load(Path(library) if library is not None else find_library())

    def session(self, scene: Union[Scene, Mapping[str, Any], str, bytes], *,
                ids: Optional[Sequence[int]] = None) -> "DistributedSession":
        """Collective: a session of this rank's bodies ``scene``, ``ids`` their
        global indices (default: the bodies' integer ids)."""
        return DistributedSession(self, scene, ids=ids)


class DistributedSession(Session):
    """This rank's part of a distributed scene: :class:`~ntscontact.Session`'s
    steps, every rank together (see the module's doc). A rank may own no
    bodies: it steps with an array of shape (0, 2) (or None) and gets the whole's
    summary."""

    _may_hold_no_bodies = True

    def __init__(self, engine: DistributedEngine, scene: Union[Scene, Mapping[str, Any], str, bytes], *,
                 ids: Optional[Sequence[int]] = None) -> None:
        self.engine = engine
        self.comm = engine.comm
        self._lib = engine._lib
        self._handle: Optional[int] = None
        self._deferred = True
        failure: Optional[BaseException] = None
        try:  # the checks of Session, then the collective creation (no rank waits for one that failed)
            super().__init__(engine, scene, keep_candidates=True)
            self._ids = [int(i) for i in (ids if ids is not None else self._default_ids())]
            if len(self._ids) != len(self.body_ids):
                raise InvalidScene(f"{len(self._ids)} global indices for {len(self.body_ids)} bodies",
                                   code="invalid_value", pointer="/bodies")
        except Exception as exc:  # any: the other ranks must hear of it, not wait
            failure = exc
        self._agree(failure)
        self._deferred = False
        self._create()

    def _default_ids(self) -> List[int]:
        if not all(isinstance(i, int) and not isinstance(i, bool) for i in self.body_ids):
            raise InvalidScene("a distributed session needs each body's global index: give ids=, or integer ids",
                               code="invalid_value", pointer="/bodies")
        return [int(i) for i in self.body_ids]

    def _agree(self, failure: Optional[BaseException], flag: bool = False) -> bool:
        """Every rank raises the lowest failing rank's error (the same code,
        message and pointer everywhere), or none does; then whether some
        rank raised ``flag`` (in the same collective)."""
        mine = None
        if failure is not None:
            code = getattr(failure, "code", "invalid_value") or "invalid_value"
            message = getattr(failure, "message", None) or str(failure)
            mine = (str(code), f"rank {self.comm.Get_rank()}: {message}", getattr(failure, "pointer", "") or "")
        every = self.comm.allgather((mine, bool(flag)))
        first = next((e for e, _ in every if e is not None), None)
        if first is not None:
            raise InvalidScene(first[1], code=first[0], pointer=first[2]) from failure
        return any(f for _, f in every)

    def _create(self) -> None:
        if self._deferred:
            return
        ids = (ctypes.c_int * max(1, len(self._ids)))(*self._ids)
        error = ctypes.c_void_p()
        handle = self._lib.ntsm_engine_create(self.comm.py2f(), self._body, len(self._body), ids, len(self._ids),
                                              self.engine.threads, ctypes.byref(error))
        if not handle:
            _raise_document(_text(self._lib, error))
        self._handle = handle
        counts = (ctypes.c_longlong * 3)()
        self._lib.ntsm_engine_counts(handle, counts)
        self.id = f"mpi-rank-{self.comm.Get_rank()}-{id(self):x}"
        self.whole_bodies, self.surface_nodes = int(counts[1]), int(counts[2])
        if int(counts[0]) != self.nodes:
            raise NtsError(f"the library counts {counts[0]} nodes, the part has {self.nodes}", code="bad_response")

    def _as_positions(self, positions: PositionsLike) -> FloatArray:
        failure: Optional[BaseException] = None
        out = None
        bad = np.zeros(0, dtype=np.int64)
        try:
            out = super()._as_positions(positions)
            bad = non_finite_rows(out)
        except Exception as exc:  # any: the other ranks must hear of it, not wait
            failure = exc
        # (a shape is judged before the values, as one process judges them)
        if self._agree(failure, flag=len(bad) > 0):
            assert out is not None
            self._refuse_non_finite(out, bad)
        assert out is not None
        return out

    def _refuse_non_finite(self, out: FloatArray, bad: npt.NDArray[np.int64]) -> None:
        """Collective, when some rank's rows ``bad`` of ``out`` hold a NaN or
        an infinity: every rank raises the error one process raises for the
        whole's positions (their bodies in global order), at the whole's
        first such row, not at a rank's own row (the library would name
        /bodies/b/nodes/n: the client's pointer, as one process's)."""
        counts = self.comm.allgather([(g, int(self._offsets[k + 1] - self._offsets[k]))
                                      for k, g in enumerate(self._ids)])
        start: Dict[int, Tuple[int, int]] = {}  # a global index: the whole's body and its first row
        row = 0
        for whole, (g, n) in enumerate(sorted(pair for part in counts for pair in part)):
            start[g] = (whole, row)
            row += n
        mine = None
        if len(bad):
            body = np.searchsorted(self._offsets, bad, side="right") - 1  # each bad row's body here
            g, b, k = min((start[self._ids[b]][1] + int(k - self._offsets[b]), int(b), int(k))
                          for b, k in zip(body, bad))
            mine = (g, start[self._ids[b]][0], int(k - self._offsets[b]), (float(out[k, 0]), float(out[k, 1])))
        g, whole, node, xy = min(m for m in self.comm.allgather(mine) if m is not None)
        raise non_finite_error(g, whole, node, np.array(xy))

    def contact(self, positions: Optional[PositionsLike] = None, **kw: Any) -> Result:
        """Collective: :meth:`Session.contact` on every rank together; a rank
        whose bodies did not move may pass None (its stored positions). The
        summary is the whole scene's (its ``bodies`` too); the forces this
        rank's nodes'."""
        # every rank checks positions (a collective), those given none their stored ones
        result = super().contact(positions if positions is not None else self._positions, **kw)
        result.summary = dataclasses.replace(result.summary, bodies=self.whole_bodies)
        return result

    def close(self) -> None:
        """Free this rank's session (not collective; twice is fine)."""
        self._closed = True
        if self._handle:
            self._lib.ntsm_engine_destroy(self._handle)
            self._handle = None

    def __del__(self) -> None:
        if getattr(self, "_handle", None):
            self.close()

    def info(self) -> Dict[str, Any]:
        """This rank's nodes, the whole scene's bodies and surface nodes, the steps taken."""
        return {"id": self.id, "nodes": self.nodes, "bodies": self.whole_bodies, "surface_nodes": self.surface_nodes,
                "steps": self.steps, "rank": self.comm.Get_rank(), "ranks": self.comm.Get_size()}

    def _post_step(self, pos: Optional[FloatArray], params: Dict[str, str], binary: bool,
                   timeout: Optional[Any], while_waiting: Optional[Callable[[], None]] = None,
                   surface: bool = False) -> Tuple[Dict[str, Any], Mapping[str, str], Any]:
        # (surface: never; a distributed session exchanges every node of its rank)
        if self._closed or not self._handle:
            raise NtsError("the session is closed", code="closed")
        outputs = 0
        for name in filter(None, params.get("outputs", "").split(",")):
            outputs |= _OUTPUT_BITS.get(name, 1 << 30)  # an unknown one: the library says so, on every rank
        if "outputs" in params and outputs == 0:
            outputs = _OUTPUT_BITS["energy"]  # the summary only
        solver = _SOLVERS.get(params["solver"], 99) if "solver" in params else -1

        def num(name: str) -> Tuple[int, float]:
            return (1, float(params[name])) if name in params else (0, 0.0)

        forces = np.empty((self.nodes, 2), dtype="<f8")
        headers, error = ctypes.c_void_p(), ctypes.c_void_p()
        data = pos.ctypes.data if pos is not None else None
        length = pos.nbytes if pos is not None else 0
        rc = self._lib.ntsm_engine_step(self._handle, data, length, *num("penalty"), *num("alpha"),
                                        *num("search_radius"), solver, ctypes.c_uint(outputs & 0xFFFFFFFF),
                                        forces.ctypes.data, ctypes.byref(headers), ctypes.byref(error))
        if rc != 0:
            _raise_document(_text(self._lib, error))
        text = _text(self._lib, headers)
        h = dict(line.split(": ", 1) for line in text.splitlines() if line)
        return {}, h, memoryview(forces).cast("B") if forces.size else memoryview(b"")  # (a rank with no node)

"""The contact engine in process: the daemon's answers without a daemon.

>>> engine = ntscontact.Engine()                      # doctest: +SKIP
>>> result = engine.contact(scene, outputs=["forces", "contacts"])
>>> with engine.session(scene) as s:                 # a solver loop
...     f = s.contact(x).force_array()

:class:`Engine` has :class:`~ntscontact.Client`'s calls (``contact``,
``validate``, ``session``) and gives the same :class:`~ntscontact.Result`, the
same errors and the same :class:`~ntscontact.Session` API, so that a program
switches between ``Engine()`` and ``Client(url)`` in one line. Both run the
same codec (``libntscontact_engine.so``, the daemon's decoding, evaluation and
encoding behind ``ntscontact/engine.h``): an answer is the daemon's, bit for
bit, ``elapsed_ms`` aside.

A session step sends the positions to the core where they lie (a contiguous
float64 array is read in place) and the forces come back as a view of the
core's own answer, freed when the last array that views it goes. ctypes
releases the GIL during every call into the library, so other Python threads
run while one evaluates; one engine serves many threads, and each session
takes its steps one at a time (a lock).

The library is looked for in ``$NTSCONTACT_LIBRARY`` (a path), then in the
package (``pip install ./clients/python`` builds and bundles it when CMake and
a C compiler are present). Without it, :class:`Engine` raises
:class:`EngineUnavailable` saying how to get it; :class:`~ntscontact.Client`
needs none of this.
"""

from __future__ import annotations

import contextlib
import ctypes
import json
import os
import threading
from pathlib import Path
from typing import Any, Callable, Dict, Iterator, List, Mapping, Optional, Sequence, Tuple, Union

from . import __version__
from .client import Client, SceneLike
from .errors import NtsError, ServerError, error_from_response
from .result import Result
from .scene import Scene, is_integer, normalize_outputs
from .session import FloatArray, Session

__all__ = ["Engine", "EngineSession", "EngineUnavailable", "LIBRARY_NAME", "find_library"]

#: The shared library's file name (built by CMake's ``ntscontact_engine`` target).
LIBRARY_NAME = "libntscontact_engine.so"

_STEP_EMPTY, _STEP_BINARY = 0, 2  # ntsj_step_body (codec.h)
#: The largest ``max_bytes`` an engine takes (a size_t that any 64-bit host holds).
MAX_BYTES = 2**62

#: The most threads an evaluation takes (the core's options table: nts_options.threads).
MAX_THREADS = 1024


class EngineUnavailable(NtsError, ImportError):
    """The in-process engine's library cannot be found or loaded."""


def locate(variable: str, name: str) -> Optional[Path]:
    """A shared library: ``$variable`` (a path, which must exist), else the
    package's copy of ``name``, else None."""
    env = os.environ.get(variable)
    if env:
        path = Path(env)
        if not path.is_file():
            raise EngineUnavailable(f"{variable}={env}: no such file", code="engine_unavailable")
        return path
    bundled = Path(__file__).resolve().parent / "_lib" / name
    return bundled if bundled.is_file() else None


def find_library() -> Path:
    """The path of ``libntscontact_engine.so``: ``$NTSCONTACT_LIBRARY``, else the
    copy bundled in the package. Raises :class:`EngineUnavailable` with what to do."""
    found = locate("NTSCONTACT_LIBRARY", LIBRARY_NAME)
    if found is not None:
        return found
    raise EngineUnavailable(
        f"the in-process engine needs {LIBRARY_NAME}, and this installation of ntscontact has none "
        "(it was installed where CMake or a C compiler was missing). Install them (Debian: apt-get install "
        "build-essential cmake pkg-config libgsl-dev libcjson-dev) and reinstall with "
        "`pip install ./clients/python` from the source tree, or build it (`cmake -S . -B build && cmake --build "
        f"build`) and set NTSCONTACT_LIBRARY=build/lib/{LIBRARY_NAME}. The HTTP Client works without it.",
        code="engine_unavailable")


_lock = threading.Lock()
_libs: Dict[str, ctypes.CDLL] = {}


def _load(path: Path) -> ctypes.CDLL:
    """Load the library once per path and declare its calls (engine.h)."""
    key = str(path)
    with _lock:
        if key in _libs:
            return _libs[key]
        try:
            lib = ctypes.CDLL(key)  # CDLL, not PyDLL: the GIL is released during each call
        except OSError as exc:
            raise EngineUnavailable(f"cannot load {key}: {exc}", code="engine_unavailable") from exc
        vp, cp, sz, i = ctypes.c_void_p, ctypes.c_char_p, ctypes.c_size_t, ctypes.c_int
        sigs: Dict[str, Tuple[Any, List[Any]]] = {
            "ntsj_engine_create": (vp, [i]),
            "ntsj_engine_destroy": (None, [vp]),
            "ntsj_engine_contact": (vp, [vp, cp, sz, i]),
            "ntsj_engine_session_create": (vp, [vp, cp, sz, ctypes.POINTER(vp)]),
            "ntsj_engine_step": (vp, [vp, vp, i, vp, sz, i, i, ctypes.POINTER(cp), ctypes.POINTER(cp)]),
            "ntsj_engine_session_counts": (None, [vp, ctypes.POINTER(ctypes.c_longlong)]),
            "ntsj_session_destroy": (None, [vp]),
            "ntsj_session_surface": (ctypes.POINTER(i), [vp, ctypes.POINTER(i)]),
            "ntsj_answer_ok": (i, [vp]),
            "ntsj_answer_status": (i, [vp]),
            "ntsj_answer_code": (cp, [vp]),
            "ntsj_answer_body": (vp, [vp]),
            "ntsj_answer_length": (sz, [vp]),
            "ntsj_answer_binary": (i, [vp]),
            "ntsj_answer_headers": (cp, [vp]),
            "ntsj_answer_free": (None, [vp]),
        }
        try:
            for name, (res, args) in sigs.items():
                fn = getattr(lib, name)
                fn.restype, fn.argtypes = res, args
            if hasattr(lib, "ntsj_engine_create_sized"):  # (a library older than max_bytes has not)
                lib.ntsj_engine_create_sized.restype = vp
                lib.ntsj_engine_create_sized.argtypes = [i, sz]
        except AttributeError as exc:
            raise EngineUnavailable(f"{key} is not ntscontact's engine library ({exc})",
                                    code="engine_unavailable") from exc
        _libs[key] = lib
        return lib


class _Answer:
    """Owns one ``ntsj_answer``: freed when the last view of its body goes."""

    __slots__ = ("lib", "ptr", "__weakref__")

    def __init__(self, lib: ctypes.CDLL, ptr: Optional[int]) -> None:
        if not ptr:
            raise MemoryError("ntscontact: out of memory in the engine")
        self.lib, self.ptr = lib, ptr

    def __del__(self) -> None:
        if self.ptr:
            self.lib.ntsj_answer_free(self.ptr)
            self.ptr = None

    @property
    def ok(self) -> bool:
        return bool(self.lib.ntsj_answer_ok(self.ptr))

    @property
    def status(self) -> int:
        return int(self.lib.ntsj_answer_status(self.ptr))

    def text(self) -> bytes:
        n = self.lib.ntsj_answer_length(self.ptr)
        return ctypes.string_at(self.lib.ntsj_answer_body(self.ptr), n) if n else b""

    def view(self) -> Any:
        """The body without a copy: a ctypes array over the library's memory
        that keeps this answer alive (numpy's views of it keep it in turn)."""
        n = self.lib.ntsj_answer_length(self.ptr)
        if n == 0:
            return b""
        buf = (ctypes.c_char * n).from_address(self.lib.ntsj_answer_body(self.ptr))
        buf._owner = self  # type: ignore[attr-defined]
        return memoryview(buf).toreadonly()  # read-only, as the daemon's bytes are

    def headers(self) -> Dict[str, str]:
        text = self.lib.ntsj_answer_headers(self.ptr).decode("ascii")
        return dict(line.split(": ", 1) for line in text.splitlines() if line)

    def raise_for_error(self, bodies: Optional[Sequence[Any]] = None) -> None:
        """The error the daemon's answer would raise in :class:`~ntscontact.Client`."""
        if self.ok:
            return
        raw = self.text()
        try:
            doc = json.loads(raw)
        except ValueError:
            doc = None
        raise error_from_response(self.status, doc, raw.decode("utf-8", "replace"), bodies)


class Engine:
    """The contact engine in process (see the module's doc).

    ``threads``: the threads of each evaluation (0, the default: serial; the
    answer's bits do not depend on it). ``max_bytes``: the largest JSON text
    a call, or a session's scene, takes (default 64 MiB, as the daemon's
    ``--max-bytes``; past it :class:`~ntscontact.PayloadTooLarge`). ``library``: the path of
    ``libntscontact_engine.so`` (default: :func:`find_library`). ``timeout``
    arguments are taken for :class:`~ntscontact.Client`'s signatures and
    ignored: a call in process runs to its end.
    """

    def __init__(self, threads: int = 0, *, library: Optional[Union[str, os.PathLike]] = None,
                 max_bytes: Optional[int] = None) -> None:
        self._ptr: Optional[int] = None
        if not is_integer(threads) or not 0 <= threads <= MAX_THREADS:
            raise ValueError(f"threads must be an integer in [0, {MAX_THREADS}], not {threads!r}")
        if max_bytes is not None and (not is_integer(max_bytes) or not 1 <= max_bytes <= MAX_BYTES):
            raise ValueError(f"max_bytes must be an integer in [1, {MAX_BYTES}], not {max_bytes!r}")
        self.library = Path(library) if library is not None else find_library()
        self._lib = _load(self.library)
        if max_bytes is not None and not hasattr(self._lib, "ntsj_engine_create_sized"):
            raise EngineUnavailable(f"{self.library} predates max_bytes: rebuild it (in a checkout: "
                                    "bash scripts/build.sh; else pip install the package again)",
                                    code="engine_unavailable")
        self.threads = int(threads)
        self.max_bytes = int(max_bytes) if max_bytes is not None else None
        # Calls in flight (the GIL is released inside them): close() waits
        # for them, so that none reads a freed engine.
        self._calls = 0
        self._idle = threading.Condition()
        self._ptr = self._new_config()
        if not self._ptr:
            raise MemoryError("ntscontact: out of memory creating the engine")
        self.version = __version__

    def _new_config(self) -> int:
        """A new ``ntsj_engine``: the engine's, or a session's own, configuration."""
        if self.max_bytes is None:
            return self._lib.ntsj_engine_create(self.threads)
        return self._lib.ntsj_engine_create_sized(self.threads, self.max_bytes)

    # ------------------------------------------------------------ lifecycle

    def close(self) -> None:
        """Free the engine once the calls in flight have returned: its calls then
        raise; its sessions go on (each holds its own state and configuration)
        until they are closed."""
        with self._idle:
            while self._calls > 0:
                self._idle.wait()
            ptr, self._ptr = self._ptr, None
        if ptr:
            self._lib.ntsj_engine_destroy(ptr)

    def __del__(self) -> None:
        if getattr(self, "_ptr", None):
            self.close()

    def __enter__(self) -> "Engine":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        sized = "" if self.max_bytes is None else f", max_bytes={self.max_bytes}"
        return f"Engine(threads={self.threads}{sized}, library={str(self.library)!r})"

    @contextlib.contextmanager
    def _engine(self) -> Iterator[int]:
        """The engine's handle for one call, which close() waits for."""
        with self._idle:
            if not self._ptr:
                raise NtsError("the engine is closed", code="closed")
            self._calls += 1
            ptr = self._ptr
        try:
            yield ptr
        finally:
            with self._idle:
                self._calls -= 1
                self._idle.notify_all()

    # ------------------------------------------------------------ calls

    def contact(self, scene: SceneLike, outputs: Optional[Union[str, Sequence[str]]] = None, *,
                history: Optional[Sequence[Mapping[str, Any]]] = None, timeout: Optional[Any] = None) -> Result:
        """:meth:`Client.contact <ntscontact.Client.contact>` in process: the same
        arguments, the same :class:`~ntscontact.Result` and errors."""
        doc = json.loads(self.contact_json(scene, outputs, history=history))
        if not isinstance(doc, dict) or not isinstance(doc.get("summary"), dict):
            raise ServerError("the engine's answer has no summary", code="bad_response", status=200)
        result = Result.from_dict(doc)
        if isinstance(scene, Scene):
            result._scene = (scene, scene.positions())
        return result.warn()

    def contact_json(self, scene: SceneLike, outputs: Optional[Union[str, Sequence[str]]] = None, *,
                     history: Optional[Sequence[Mapping[str, Any]]] = None) -> bytes:
        """The result document as UTF-8 bytes, the daemon's for ``POST /v1/contact``
        (``elapsed_ms`` aside): for a program that stores or forwards it. Errors
        are raised as :meth:`contact` raises them."""
        body, ids = Client._encode(scene, normalize_outputs(outputs), history)
        with self._engine() as ptr:
            answer = _Answer(self._lib, self._lib.ntsj_engine_contact(ptr, body, len(body), 0))
        answer.raise_for_error(ids)
        return answer.text()

    def validate(self, scene: SceneLike, *, timeout: Optional[Any] = None) -> Dict[str, Any]:
        """:meth:`Client.validate <ntscontact.Client.validate>` in process."""
        body, ids = Client._encode(scene, None)
        with self._engine() as ptr:
            answer = _Answer(self._lib, self._lib.ntsj_engine_contact(ptr, body, len(body), 1))
        answer.raise_for_error(ids)
        doc: Dict[str, Any] = json.loads(answer.text())
        return doc

    def session(self, scene: SceneLike, *, timeout: Optional[Any] = None, keep_contacts: bool = False,
                keep_candidates: bool = True, skin: Optional[float] = None,
                exchange: str = "all") -> "EngineSession":
        """:meth:`Client.session <ntscontact.Client.session>` in process: an
        :class:`EngineSession`, the :class:`~ntscontact.Session` API."""
        return EngineSession(self, scene, timeout=timeout, keep_contacts=keep_contacts,
                             keep_candidates=keep_candidates, skin=skin, exchange=exchange)


class EngineSession(Session):
    """A :class:`~ntscontact.Session` held in process by an :class:`Engine`:
    the same steps, results and errors, with no HTTP between them."""

    def __init__(self, engine: Engine, scene: SceneLike, **kw: Any) -> None:
        self.engine = engine
        self._lib = engine._lib
        self._handle: Optional[int] = None
        self._config: Optional[int] = None
        self._closed = False  # before anything that may raise: __del__ reads it
        self._step_lock = threading.Lock()
        # The session's own configuration (the engine's threads): it outlives
        # Engine.close(), as the session's state does.
        with engine._engine():
            self._config = engine._new_config()
        if not self._config:
            raise MemoryError("ntscontact: out of memory creating a session")
        super().__init__(engine, scene, **kw)

    def _create(self) -> None:
        out = ctypes.c_void_p()
        answer = _Answer(self._lib, self._lib.ntsj_engine_session_create(
            self._config, self._body, len(self._body), ctypes.byref(out)))
        answer.raise_for_error(self.body_ids)
        self._handle = out.value
        counts = self._counts()
        self.id = f"in-process-{id(self):x}"
        self.surface_nodes = counts[2]
        if counts[1] != self.nodes:
            raise ServerError(f"the engine counts {counts[1]} nodes, the scene has {self.nodes}", code="bad_response")
        if self.exchange == "surface":
            self.surface = self._check_surface(self._surface_nodes())

    def _surface_nodes(self) -> List[int]:
        count = ctypes.c_int(0)
        with self._step_lock:
            if self._closed or not self._handle:
                raise NtsError("the session is closed", code="closed")
            ptr = self._lib.ntsj_session_surface(self._handle, ctypes.byref(count))
            return [int(ptr[k]) for k in range(count.value)] if ptr else []

    def _counts(self) -> List[int]:
        """bodies, nodes, surface nodes, steps, bytes: read between steps."""
        out = (ctypes.c_longlong * 5)()
        with self._step_lock:
            if self._closed or not self._handle:
                raise NtsError("the session is closed", code="closed")
            self._lib.ntsj_engine_session_counts(self._handle, out)
        return list(out)

    def close(self) -> None:
        """Free the session's state in the library (twice is fine)."""
        with self._step_lock:
            if self._closed and not self._config:
                return
            self._closed = True
            if self._handle:
                self._lib.ntsj_session_destroy(self._handle)
                self._handle = None
            if self._config:
                self._lib.ntsj_engine_destroy(self._config)
                self._config = None

    def __del__(self) -> None:
        if getattr(self, "_handle", None) or getattr(self, "_config", None):
            self.close()

    def info(self) -> Dict[str, Any]:
        """What the session holds: bodies, nodes, surface nodes, steps, bytes
        (the daemon's info without its timings: a session in process never
        expires). A closed session raises."""
        bodies, nodes, surface, steps, memory = self._counts()
        return {"id": self.id, "bodies": bodies, "nodes": nodes, "surface_nodes": surface, "steps": steps,
                "memory_bytes": memory}

    def _post_step(self, pos: Optional[FloatArray], params: Dict[str, str], binary: bool,
                   timeout: Optional[Any], while_waiting: Optional[Callable[[], None]] = None,
                   surface: bool = False) -> Tuple[Dict[str, Any], Mapping[str, str], Any]:
        """One step in the library: the positions read in place, the binary
        answer's forces given back as a view of the library's memory."""
        names = (ctypes.c_char_p * max(1, len(params)))(*(k.encode() for k in params))
        values = (ctypes.c_char_p * max(1, len(params)))(*(v.encode() for v in params.values()))
        kind, data, length = _STEP_EMPTY, None, 0
        if pos is not None:  # contiguous little-endian float64 (Session._as_positions)
            kind, data, length = _STEP_BINARY, pos.ctypes.data, pos.nbytes
        with self._step_lock:
            if self._closed:
                raise NtsError("the session is closed", code="closed")
            answer = _Answer(self._lib, self._lib.ntsj_engine_step(
                self._config, self._handle, kind, data, length, int(binary), len(params), names, values))
        answer.raise_for_error(self.body_ids)
        if binary:
            return {}, answer.headers(), answer.view()
        return json.loads(answer.text()), {}, b""


"""HTTP client of ``ntscontactd`` on one :class:`requests.Session`."""

from __future__ import annotations

import json
import threading
from dataclasses import dataclass
from typing import Any, Callable, Dict, List, Mapping, Optional, Sequence, Tuple, Union
from urllib.parse import urlencode, urljoin

import requests
import urllib3
from requests.adapters import HTTPAdapter
from requests.cookies import MockRequest, extract_cookies_to_jar
from urllib3.util import parse_url
from urllib3.util.retry import Retry

from . import __version__
from ._wire import Wire, WireError, WireTimeout
from .errors import InvalidScene, NtsError, ServerError, ServiceUnavailable, Timeout, error_from_response, tls_error
from .result import Result
from .scene import Scene, dump_document, json_kind, normalize_outputs, scene_document
from .session import Session

__all__ = ["Client", "USER_AGENT", "DEFAULT_URL"]

USER_AGENT = f"ntscontact-python/{__version__}"
DEFAULT_URL = "http://127.0.0.1:8080"

SceneLike = Union[Scene, Mapping[str, Any], str, bytes]
TimeoutLike = Union[float, Tuple[float, float]]
BodyLike = Union[bytes, memoryview]


@dataclass(frozen=True)
class Answer:
    """One HTTP answer, read whole: status, headers (case-insensitive), bytes."""

    status_code: int
    headers: Mapping[str, str]
    content: Union[bytes, bytearray]

    @property
    def text(self) -> str:
        return self.content.decode("utf-8", "replace")

    def json(self) -> Any:
        """The body as JSON (ValueError when it is not)."""
        return json.loads(self.content)


def history_document(history: Any) -> List[Any]:
    """``history=`` as sent: a list of anchors (mappings, a previous result's
    :attr:`Result.history`). Not a sequence: refused as the service refuses
    it (``invalid_type`` at ``/history``); its entries are the service's to
    read, in its order."""
    if not isinstance(history, Sequence) or isinstance(history, (str, bytes, bytearray)):
        raise InvalidScene(f'expected an array of anchors (a previous result\'s "history"), got {json_kind(history)}',
                           code="invalid_type", pointer="/history")
    return [dict(a) if isinstance(a, Mapping) else a for a in history]


class _SetCookies:
    """An answer's Set-Cookie values as http.cookiejar reads a response."""

    def __init__(self, values: List[str]) -> None:
        self._values = values

    def info(self) -> "_SetCookies":
        return self

    def get_all(self, name: str, default: Optional[List[str]] = None) -> List[str]:
        return list(self._values) if name.lower() == "set-cookie" else (default or [])


def _urllib3_timeout(t: Optional[TimeoutLike]) -> urllib3.Timeout:
    """requests' reading of a timeout: (connect, read), or one for both."""
    if isinstance(t, tuple):
        return urllib3.Timeout(connect=t[0], read=t[1])
    return urllib3.Timeout(connect=t, read=t)


class Client:
    """A client of the contact service.

    ``timeout`` (seconds, or ``(connect, read)``) applies to every call unless a
    call gives its own. ``retries`` is the number of retries of a *connection*
    failure (refused, reset before the request was sent, DNS): the request
    never reached the service, so even a POST is safe to repeat. Nothing else is
    retried: not read timeouts, not 5xx, not 503.

    ``token`` is a bearer token of the daemon's ``--token-file``; ``verify`` is
    what requests checks an https daemon's certificate against (a CA file).

    ``trust_env`` (default False) lets requests read proxies and ``.netrc`` from
    the environment; the service normally runs next to the solver, and that
    lookup costs about a millisecond per call, as much as a small evaluation.

    :meth:`session` holds a scene in the service for a solver loop: each step
    then sends only positions (see :class:`Session`).

    Use as a context manager, or call :meth:`close`.
    """

    def __init__(
        self,
        base_url: str = DEFAULT_URL,
        timeout: TimeoutLike = 30.0,
        *,
        retries: int = 3,
        backoff: float = 0.1,
        trust_env: bool = False,
        http: Optional[requests.Session] = None,
        token: Optional[str] = None,
        verify: Union[bool, str] = True,
        wire: bool = True,
    ) -> None:
        self.base_url = base_url.rstrip("/")
        self.timeout = timeout
        #: The requests.Session all calls go through (``http=`` to bring your own).
        self.http = http if http is not None else requests.Session()
        self.http.trust_env = trust_env
        retry = Retry(
            total=None,
            connect=retries,
            read=False,  # read errors (and read timeouts) re-raised at once, never retried
            status=0,
            redirect=0,
            other=0,
            backoff_factor=backoff,
            allowed_methods=None,  # POST too: only connect failures are retried
            raise_on_status=False,
            respect_retry_after_header=False,
        )
        adapter = HTTPAdapter(max_retries=retry)
        self.http.mount("http://", adapter)
        self.http.mount("https://", adapter)
        self._adapter = adapter
        # (base_url, a request to it, its path, whether it carries credentials): what _pool and _send read of it
        self._base: Optional[Tuple[str, requests.PreparedRequest, str, bool]] = None
        self.http.headers.update({"User-Agent": USER_AGENT, "Accept": "application/json"})
        if token is not None:  # the daemon's --token-file
            self.http.headers["Authorization"] = f"Bearer {token}"
        self.http.verify = verify  # for https: True, or the path of a CA bundle / the daemon's certificate
        #: Calls to a plain http:// service on a kept connection of our own
        #: (``_wire``), when requests' machinery is not needed; False: urllib3's pool.
        self.wire = wire
        self._wire: Optional[Wire] = None
        self._wire_lock = threading.Lock()

    # ------------------------------------------------------------ lifecycle

    def close(self) -> None:
        """Close the HTTP connection pool (``with Client(...)`` does it on exit)."""
        with self._wire_lock:
            if self._wire is not None:
                self._wire.retire()  # (another thread's call on it closes it when it ends)
                self._wire = None
        self.http.close()

    def __enter__(self) -> "Client":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"Client({self.base_url!r}, timeout={self.timeout!r})"

    # ------------------------------------------------------------ endpoints

    def contact(
        self,
        scene: SceneLike,
        outputs: Optional[Union[str, Sequence[str]]] = None,
        *,
        history: Optional[Sequence[Mapping[str, Any]]] = None,
        timeout: Optional[TimeoutLike] = None,
    ) -> Result:
        """``POST /v1/contact``. ``scene`` is a :class:`Scene` (checked before it is
        sent), a dict, or JSON text sent as it is. ``outputs`` (e.g.
        ``["forces", "contacts"]``) overrides the scene's ``options.outputs``.
        ``history``: with friction, the anchors a previous result ended with
        (:attr:`Result.history`), from which this evaluation goes on
        (docs/model.md §14); the result's own history is the next call's."""
        body, ids = self._encode(scene, normalize_outputs(outputs), history)
        doc = self._request("POST", "/v1/contact", body=body, timeout=timeout, body_ids=ids)
        if not isinstance(doc.get("summary"), dict):
            raise ServerError(f"POST {self.base_url}/v1/contact: the answer has no summary", code="bad_response",
                              status=200)
        result = Result.from_dict(doc)
        if isinstance(scene, Scene):
            result._scene = (scene, scene.positions())  # the topology, and the positions evaluated
        return result.warn()

    def session(self, scene: SceneLike, *, timeout: Optional[TimeoutLike] = None,
                keep_contacts: bool = False, keep_candidates: bool = True,
                skin: Optional[float] = None, exchange: str = "all") -> Session:
        """``POST /v1/scenes``: a :class:`Session` holding ``scene`` in the service, for
        a solver loop (``with client.session(scene) as s: s.contact(x)``). The
        session is deleted when the ``with`` block ends (or on ``close()``).
        ``keep_contacts``: each step's contacts carry ``previous`` and ``persisted``
        (their match to the last step's), the summary ``contact_changes``.
        ``keep_candidates`` (default on) and ``skin`` (a length; default 0.3 times
        the search radius): the session's kept candidate list (docs/sessions.md),
        which changes the time of a step, never its answer. ``exchange="surface"``:
        binary steps send and receive the surface nodes' rows alone
        (``?nodes=surface``), the same answers (docs/sessions.md)."""
        return Session(self, scene, timeout=timeout, keep_contacts=keep_contacts, keep_candidates=keep_candidates,
                       skin=skin, exchange=exchange)

    def validate(self, scene: SceneLike, *, timeout: Optional[TimeoutLike] = None) -> Dict[str, Any]:
        """``POST /v1/validate``: the service's check of a scene without evaluating it.
        Returns the service's report; an invalid scene raises :class:`InvalidScene`."""
        body, ids = self._encode(scene, None)
        return self._request("POST", "/v1/validate", body=body, timeout=timeout, body_ids=ids)

    def health(self, *, timeout: Optional[TimeoutLike] = None) -> Dict[str, Any]:
        """``GET /v1/health``: status, version, build options, uptime, requests served."""
        return self._request("GET", "/v1/health", timeout=timeout)

    def schema(self, name: str, *, timeout: Optional[TimeoutLike] = None) -> Dict[str, Any]:
        """``GET /v1/schemas/{name}`` for ``name`` in scene, result, error."""
        return self._request("GET", f"/v1/schemas/{name}", timeout=timeout)

    def openapi(self, *, timeout: Optional[TimeoutLike] = None) -> Dict[str, Any]:
        """``GET /v1/openapi.json``."""
        return self._request("GET", "/v1/openapi.json", timeout=timeout)

    # ------------------------------------------------------------ internals

    @staticmethod
    def _encode(scene: SceneLike, outputs: Optional[Sequence[str]],
                history: Optional[Sequence[Mapping[str, Any]]] = None) -> Tuple[bytes, Optional[List[Any]]]:
        if isinstance(scene, Scene):
            scene.check()
            doc: Any = scene.to_dict()
            ids: Optional[List[Any]] = list(scene.body_ids)
        elif isinstance(scene, Mapping):
            doc = dict(scene)
            ids = [b.get("id") for b in doc.get("bodies", []) if isinstance(b, Mapping)] \
                if isinstance(doc.get("bodies"), list) else None
        elif isinstance(scene, (str, bytes, bytearray)):
            raw = scene.encode("utf-8") if isinstance(scene, str) else bytes(scene)
            if outputs is None and history is None:
                return raw, None
            doc = scene_document(raw)
            ids = None
        else:
            raise TypeError(f"scene must be a Scene, a mapping or JSON text, not {type(scene).__name__}")
        if outputs is not None:
            doc = dict(doc)
            doc["options"] = dict(doc.get("options") or {}, outputs=list(outputs))
        if history is not None:
            doc = dict(doc, history=history_document(history))
        return dump_document(doc), ids

    def _base_parts(self) -> Tuple[str, requests.PreparedRequest, str, bool]:
        """base_url read once (it may be changed between calls)."""
        if self._base is None or self._base[0] != self.base_url:
            u = parse_url(self.base_url)
            self._base = (self.base_url, self._prepared_for(self.base_url + "/"), u.path or "", bool(u.auth))
        return self._base

    def _direct(self, url: str) -> bool:
        """Whether none of requests' per-call machinery is in play for ``url``
        (no proxies or environment, auth, params, hooks, cookies, credentials
        in the URL, or an adapter of the caller's): then a call may skip
        requests' 1 ms of merging and hooks (a third of a session step at 66k
        nodes, docs/benchmarks.md)."""
        h = self.http
        adapter = h.get_adapter(url)
        credentials = self._base_parts()[3]
        return not (adapter is not self._adapter or h.trust_env or h.proxies or h.auth is not None
                    or len(h.cookies) > 0 or h.params or any(h.hooks.values()) or credentials
                    or not hasattr(adapter, "get_connection_with_tls_context"))

    def _pool(self, url: str) -> Optional[urllib3.HTTPConnectionPool]:
        """The connection pool of requests' own adapter for ``url`` when the
        call may be direct: the same pool, retries, TLS settings and headers.
        None: through requests."""
        if not self._direct(url):
            return None
        h = self.http
        return self._adapter.get_connection_with_tls_context(self._base_parts()[1], h.verify, None, h.cert)

    def _wire_for(self, url: str) -> Optional[Wire]:
        """Our own kept connection (``_wire``) for a plain http:// service
        when the call may be direct: a 1,024-node step 0.54-0.57 ms where
        urllib3's took 1.2-1.35 (docs/benchmarks.md). None: the pool or requests."""
        if not self.wire or not url.startswith("http://") or not self._direct(url):
            with self._wire_lock:  # (https now, or the machinery: the wire kept for nothing)
                if self._wire is not None:
                    self._wire.retire()
                    self._wire = None
            return None
        with self._wire_lock:  # one wire a client: made and replaced by one thread at a time
            w = self._wire
            if w is None or w.base_url != self.base_url:
                if w is not None:
                    w.retire()
                u = parse_url(self.base_url)
                host = (u.host or "").strip("[]")
                retry = self._adapter.max_retries
                w = self._wire = Wire(host, u.port or 80, retries=int(retry.connect or 0),
                                      backoff=float(retry.backoff_factor), netloc=u.netloc)
                w.base_url = self.base_url
            return w

    @staticmethod
    def _prepared_for(url: str) -> requests.PreparedRequest:
        return requests.Request("GET", url).prepare()

    def _via_requests(self, method: str, url: str, body: Optional[BodyLike], headers: Optional[Mapping[str, str]],
                      params: Optional[Mapping[str, str]], t: Optional[TimeoutLike]) -> Answer:
        data = body.tobytes() if isinstance(body, memoryview) else body
        r = self.http.request(method, url, data=data, headers=headers, params=params, timeout=t)
        return Answer(r.status_code, r.headers, r.content)

    def _send(self, method: str, path: str, *, body: Optional[BodyLike] = None,
              headers: Optional[Mapping[str, str]] = None, params: Optional[Mapping[str, str]] = None,
              timeout: Optional[TimeoutLike] = None, while_waiting: Optional[Callable[[], None]] = None) -> Answer:
        """One call, its answer read whole (one read of its Content-Length, not
        requests' 10 kB chunks), the connection back to the pool. A failure
        to connect or to hear back raises :class:`ServiceUnavailable`,
        :class:`Timeout` or :class:`TLSError`; an HTTP status is the caller's.
        ``while_waiting``: the caller's work, called once, while the service
        computes the answer when the call is on our own connection, else
        before the call."""
        url = self.base_url + path
        t = self.timeout if timeout is None else timeout
        wire = self._wire_for(url)
        sent: Optional[Tuple[Answer, Optional[str]]] = None
        if wire is not None and wire.lock.acquire(blocking=False):  # (busy: another thread's call; the pool)
            try:
                if not wire.retired:  # (replaced or closed meanwhile: the pool)
                    sent = self._send_wire(wire, method, url, path, body, headers, params, t, while_waiting)
            finally:
                wire.lock.release()
        if sent is None and while_waiting is not None:
            while_waiting()
        try:
            if sent is not None:  # (a redirect followed as on the pool's path, its failures said alike)
                answer, location = sent
                return self._follow(method, url, answer.status_code, location, body, headers, t) if location else answer
            pool = self._pool(url)
            if pool is None:
                return self._via_requests(method, url, body, headers, params, t)
            resp = pool.urlopen(method, self._target(path, params), body=body, headers=self._merged(headers),
                                redirect=False, assert_same_host=False, preload_content=False,
                                decode_content=False, retries=self._adapter.max_retries, timeout=_urllib3_timeout(t))
            try:
                content = resp.read(decode_content=True)
            finally:
                resp.release_conn()
            if "set-cookie" in resp.headers:  # kept as requests keeps them: later calls go through requests
                extract_cookies_to_jar(self.http.cookies, self._prepared_for(url), resp)
            location = resp.get_redirect_location()
            if location:
                return self._follow(method, url, resp.status, location, body, headers, t)
            return Answer(resp.status, resp.headers, content)
        except urllib3.exceptions.MaxRetryError as exc:  # requests' reading of it
            reason = exc.reason
            if isinstance(reason, urllib3.exceptions.SSLError):
                raise tls_error(method, url, exc) from exc
            if isinstance(reason, urllib3.exceptions.ConnectTimeoutError) and \
                    not isinstance(reason, urllib3.exceptions.NewConnectionError):
                raise Timeout(f"{method} {url}: no answer within the timeout ({exc})", code="timeout") from exc
            raise ServiceUnavailable(f"{method} {url}: cannot connect ({exc})", code="unreachable") from exc
        except urllib3.exceptions.NewConnectionError as exc:  # (a TimeoutError subclass in urllib3: first)
            raise ServiceUnavailable(f"{method} {url}: cannot connect ({exc})", code="unreachable") from exc
        except (requests.Timeout, urllib3.exceptions.TimeoutError) as exc:
            raise Timeout(f"{method} {url}: no answer within the timeout ({exc})", code="timeout") from exc
        except (requests.exceptions.SSLError, urllib3.exceptions.SSLError) as exc:  # said as what it is
            raise tls_error(method, url, exc) from exc
        except (requests.ConnectionError, urllib3.exceptions.ProtocolError, urllib3.exceptions.ClosedPoolError) as exc:
            raise ServiceUnavailable(f"{method} {url}: cannot connect, or the answer was cut ({exc})",
                                     code="unreachable") from exc
        except (requests.RequestException, urllib3.exceptions.HTTPError) as exc:
            raise NtsError(f"{method} {url}: {exc}", code="request_failed") from exc

    def _send_wire(self, wire: Wire, method: str, url: str, path: str, body: Optional[BodyLike],
                   headers: Optional[Mapping[str, str]], params: Optional[Mapping[str, str]],
                   t: Optional[TimeoutLike], while_waiting: Optional[Callable[[], None]] = None
                   ) -> Tuple[Answer, Optional[str]]:
        """:meth:`_send` on our own connection: the answer, and where a
        redirect sends the call (for :meth:`_follow`); the same headers,
        cookies and errors as the pool's path."""
        connect_t, read_t = t if isinstance(t, tuple) else (t, t)
        try:
            status, hdrs, content, cookies = wire.exchange(method, self._target(path, params), self._merged(headers),
                                                           body, connect_t, read_t, while_waiting)
        except WireTimeout as exc:
            raise Timeout(f"{method} {url}: no answer within the timeout ({exc})", code="timeout") from exc
        except WireError as exc:
            what = "cannot connect" if exc.connect else "cannot connect, or the answer was cut"
            raise ServiceUnavailable(f"{method} {url}: {what} ({exc})", code="unreachable") from exc
        if cookies:  # kept as requests keeps them: later calls go through requests
            self.http.cookies.extract_cookies(_SetCookies(cookies), MockRequest(self._prepared_for(url)))
        location = hdrs.get("location") if status in (301, 302, 303, 307, 308) else None
        return Answer(status, hdrs, content), location

    def _merged(self, headers: Optional[Mapping[str, str]]) -> Dict[str, str]:
        """The call's headers over the client's, names matched in any case."""
        merged = dict(self.http.headers)
        if headers:
            names = {k.lower(): k for k in merged}
            for k, v in headers.items():
                merged.pop(names.get(k.lower(), k), None)
                merged[k] = v
        return merged

    def _target(self, path: str, params: Optional[Mapping[str, str]]) -> str:
        """The request target: base_url's path prefix, the path, the query."""
        return (self._base_parts()[2] + path or "/") + ("?" + urlencode(params) if params else "")

    def _follow(self, method: str, url: str, status: int, location: str, body: Optional[BodyLike],
                headers: Optional[Mapping[str, str]], t: Optional[TimeoutLike]) -> Answer:
        """A redirect followed through requests, as requests would have from
        here on (its rebuild_method)."""
        to_get = (status in (302, 303) and method != "HEAD") or (status == 301 and method == "POST")
        return self._via_requests("GET" if to_get else method, urljoin(url, location),
                                  None if to_get else body, headers, None, t)

    def _call(self, method: str, path: str, *, body: Optional[BodyLike] = None,
              headers: Optional[Mapping[str, str]] = None, params: Optional[Mapping[str, str]] = None,
              timeout: Optional[TimeoutLike] = None, body_ids: Optional[List[Any]] = None, expect_json: bool = True,
              empty_ok: bool = False, while_waiting: Optional[Callable[[], None]] = None
              ) -> Tuple[Dict[str, Any], Answer]:
        """A call and its answer: a 4xx or 5xx raised as the service's error
        (its body's ids name the bodies), else the JSON object it carries
        (``{}`` when no JSON is expected, or for a 204 when ``empty_ok``)."""
        resp = self._send(method, path, body=body, headers=headers, params=params, timeout=timeout,
                          while_waiting=while_waiting)
        if resp.status_code >= 400:
            try:
                doc = resp.json()
            except ValueError:
                doc = None
            raise error_from_response(resp.status_code, doc, resp.text, body_ids)
        if not expect_json or (empty_ok and resp.status_code == 204):
            return {}, resp
        try:
            doc = resp.json()
        except ValueError:
            doc = None
        if not isinstance(doc, dict):
            raise ServerError(f"{method} {self.base_url + path}: the answer is not a JSON object: "
                              f"{resp.text[:200]!r}", code="bad_response", status=resp.status_code)
        return doc, resp

    def _request(
        self,
        method: str,
        path: str,
        *,
        body: Optional[bytes] = None,
        timeout: Optional[TimeoutLike] = None,
        body_ids: Optional[List[Any]] = None,
    ) -> Dict[str, Any]:
        headers = {"Content-Type": "application/json"} if body is not None else None
        return self._call(method, path, body=body, headers=headers, timeout=timeout, body_ids=body_ids)[0]

"""One kept HTTP/1.1 connection, spoken directly on its socket.

A session step at a thousand nodes costs the service 0.16 ms, and through
urllib3 and http.client the client's step took 1.2-1.35 ms (header objects,
the email parser, a send per header block): on this connection 0.54-0.57 ms
(docs/benchmarks.md, "Sessions through the Python client"). This
module writes a request's head in one buffer, sends it and the body from the
caller's memory in one ``sendmsg``, and reads the answer's head and its
``Content-Length`` bytes straight into one buffer.

It serves plain ``http://`` only, and only a :class:`Client` whose requests
session needs none of requests' machinery (the same conditions as the
direct path to urllib3's pool; ``Client._wire_for``); TLS, proxies, auth
objects and cookies stay with requests. What it must keep of requests'
behaviour, it keeps: connection failures retried as ``Retry(connect=N)``
would, a connection the peer closed while idle replaced before use (never a
request sent twice once sent whole), read timeouts, ``Connection: close``,
chunked and close-delimited answers, gzip or deflate bodies.
"""

from __future__ import annotations

import re
import select
import socket
import threading
import time
import zlib
from typing import Callable, Dict, List, Mapping, Optional, Tuple, Union

__all__ = ["Wire", "WireHeaders", "WireError", "WireTimeout"]

_OWN_HEADERS = frozenset(("host", "content-length", "transfer-encoding", "accept-encoding"))
_BAD_HEAD = re.compile(r"[\r\n\0]")
_HEAD_LIMIT = 1 << 16  # an answer's head longer than this is refused (the daemon's are about 1 kB)
_CHUNK = 1 << 16
_FIRST = 1 << 14  # the first read of an answer: its head and the start of its body


class WireError(OSError):
    """The connection failed; ``connect``: no connection was made (the
    request never left). A request sent whole is never sent again."""

    def __init__(self, message: str, *, connect: bool = False) -> None:
        super().__init__(message)
        self.connect = connect


class WireTimeout(WireError):
    """No answer (or no connection) within the timeout."""


class WireHeaders(Dict[str, str]):
    """An answer's headers, read case-insensitively (stored lower-case)."""

    def __getitem__(self, key: str) -> str:
        return dict.__getitem__(self, key.lower())

    def get(self, key: str, default: Optional[str] = None) -> Optional[str]:  # type: ignore[override]
        return dict.get(self, key.lower(), default)

    def __contains__(self, key: object) -> bool:
        return isinstance(key, str) and dict.__contains__(self, key.lower())


class Wire:
    """A kept connection to ``host:port``; :meth:`exchange` is one request and
    its whole answer. ``lock`` is held by the caller around an exchange: one
    request at a time on a connection (another thread's call goes elsewhere)."""

    def __init__(self, host: str, port: int, *, retries: int = 3, backoff: float = 0.1,
                 netloc: Optional[str] = None) -> None:
        self.host, self.port = host, port
        self.netloc = netloc or (f"[{host}]:{port}" if ":" in host else f"{host}:{port}")  # the Host header
        self.retries, self.backoff = retries, backoff
        self.lock = threading.Lock()
        self.sock: Optional[socket.socket] = None
        self.base_url = ""  # the client's base_url it serves (Client._wire_for)
        self.retired = False  # replaced or closed by its client: serves no more calls
        self.connections = 0  # connections opened (tests: one for many steps)
        self.exchanges = 0

    def retire(self) -> None:
        """No more calls: the connection closed now, or by the call on it
        when it ends (another thread's: not waited for)."""
        self.retired = True
        if self.lock.acquire(blocking=False):
            try:
                self.close()
            finally:
                self.lock.release()

    def close(self) -> None:
        if self.sock is not None:
            try:
                self.sock.close()
            finally:
                self.sock = None

    # ------------------------------------------------------------ connecting

    def _dropped(self) -> bool:
        """The idle connection is readable: the peer closed it (or sent
        something unasked); it cannot carry a request. (poll, not select:
        select refuses descriptors from 1024 on, as a large solver holds.)"""
        assert self.sock is not None
        try:
            if hasattr(select, "poll"):
                p = select.poll()
                p.register(self.sock, select.POLLIN)
                return bool(p.poll(0))
            readable, _, _ = select.select([self.sock], [], [], 0)
        except (OSError, ValueError):
            return True
        return bool(readable)

    def _connect(self, connect_timeout: Optional[float]) -> socket.socket:
        """A new connection, connection failures retried ``retries`` times
        (urllib3's Retry: no wait before the first retry, then backoff,
        doubling)."""
        errors = 0
        while True:
            try:
                sock = socket.create_connection((self.host, self.port), timeout=connect_timeout)
            except socket.timeout as exc:
                err: WireError = WireTimeout(f"no connection within the timeout ({exc})", connect=True)
            except OSError as exc:
                err = WireError(f"cannot connect ({exc})", connect=True)
            else:
                sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
                self.connections += 1
                return sock
            errors += 1
            if errors > self.retries:
                raise err
            if errors > 1:
                time.sleep(min(120.0, self.backoff * 2 ** (errors - 1)))

    # ------------------------------------------------------------ one call

    def exchange(self, method: str, target: str, headers: Mapping[str, str], body: Union[bytes, memoryview, None],
                 connect_timeout: Optional[float], read_timeout: Optional[float],
                 while_waiting: Optional[Callable[[], None]] = None
                 ) -> Tuple[int, WireHeaders, Union[bytes, bytearray], List[str]]:
        """``method target`` with ``headers`` (Host and Content-Length are
        added) and ``body``: (status, headers, body, Set-Cookie values).
        ``while_waiting`` is called once the request is sent, before its
        answer is read: the caller's work done while the service computes."""
        payload = memoryview(body if body is not None else b"").cast("B")
        lines = [f"{method} {target} HTTP/1.1", f"Host: {self.netloc}"]
        for k, v in headers.items():
            if k.lower() in _OWN_HEADERS:  # framing is the wire's: never twice
                continue
            if not k or ":" in k or _BAD_HEAD.search(k) or _BAD_HEAD.search(str(v)):
                # as http.client refuses them: a CR or LF in a value (a token
                # read with its newline) would end the head there, and the
                # daemon misread the rest
                raise ValueError(f"invalid header {k!r}: {str(v)[:40]!r} (a CR, LF or NUL, or a bad name)")
            lines.append(f"{k}: {v}")
        if _BAD_HEAD.search(target) or " " in target:
            raise ValueError(f"invalid target {target[:80]!r}")
        lines.append("Accept-Encoding: gzip, deflate")  # what _read_answer decodes
        if payload.nbytes or method in ("POST", "PUT", "PATCH"):
            lines.append(f"Content-Length: {payload.nbytes}")
        head = ("\r\n".join(lines) + "\r\n\r\n").encode("latin-1")
        for attempt in range(2):
            reused = self.sock is not None
            if reused and self._dropped():
                self.close()
                reused = False
            if self.sock is None:
                self.sock = self._connect(connect_timeout)
            sock = self.sock
            sock.settimeout(connect_timeout)  # (urllib3 sends under the connect timeout, reads under the read one)
            try:
                _send_all(sock, head, payload)
            except socket.timeout as exc:
                self.close()
                raise WireTimeout(f"no answer within the timeout (sending: {exc})") from exc
            except OSError as exc:
                # The daemon may have answered before reading the whole body
                # (413, 401, 503: then it closes): that answer is the call's.
                early = self._early_answer(sock, method, read_timeout)
                if early is not None:
                    self.exchanges += 1
                    return early
                self.close()
                # A kept connection the peer closed as it was used, without a
                # word: the request was not sent whole, so not served: once
                # more on a new one.
                if reused and attempt == 0:
                    continue
                raise WireError(f"the connection failed while sending ({exc})") from exc
            except BaseException:  # (an interrupt): half a request must not stay on the connection
                self.close()
                raise
            break
        try:
            if while_waiting is not None:
                while_waiting()
            sock.settimeout(read_timeout)
            status, hdrs, content, cookies, keep = _read_answer(sock, method)
        except socket.timeout as exc:
            self.close()
            raise WireTimeout(f"no answer within the timeout ({exc})") from exc
        except OSError as exc:
            self.close()
            raise WireError(f"the answer was cut ({exc})") from exc
        except BaseException:  # (an interrupt, or the caller's work failed): its answer is never read
            self.close()
            raise
        if not keep or self.retired:
            self.close()
        self.exchanges += 1
        return status, hdrs, content, cookies

    def _early_answer(self, sock: socket.socket, method: str, read_timeout: Optional[float]
                      ) -> Optional[Tuple[int, WireHeaders, Union[bytes, bytearray], List[str]]]:
        """The answer the peer sent before the request was sent whole, if
        any; the connection is closed either way."""
        try:
            sock.settimeout(read_timeout)
            status, hdrs, content, cookies, _ = _read_answer(sock, method)
        except (OSError, ValueError):
            return None
        finally:
            self.close()
        return status, hdrs, content, cookies


def _send_all(sock: socket.socket, head: bytes, payload: memoryview) -> None:
    """The head and the body in one ``sendmsg`` (the body from its own memory,
    not copied), continued where a partial send stopped."""
    parts = [memoryview(head), payload] if payload.nbytes else [memoryview(head)]
    while parts:
        sent = sock.sendmsg(parts)
        while parts and sent >= parts[0].nbytes:
            sent -= parts[0].nbytes
            parts.pop(0)
        if parts and sent:
            parts[0] = parts[0][sent:]


def _recv_into(sock: socket.socket, view: memoryview) -> int:
    n = sock.recv_into(view)
    if n == 0:
        raise ConnectionResetError("the peer closed the connection")
    return n


def _read_answer(sock: socket.socket, method: str
                 ) -> Tuple[int, WireHeaders, Union[bytes, bytearray], List[str], bool]:
    buf = bytearray(_FIRST)  # (the daemon's heads are about 1 kB; it grows to the head's limit)
    have = 0
    while True:  # interim 1xx answers are skipped
        while True:
            end = buf.find(b"\r\n\r\n", 0, have)
            if end >= 0:
                break
            if have >= _HEAD_LIMIT:
                raise WireError("an answer's head longer than 64 kB")
            if have == len(buf):
                buf.extend(bytes(len(buf)))
            have += _recv_into(sock, memoryview(buf)[have:])
        lines = bytes(buf[:end]).decode("latin-1").split("\r\n")
        rest = bytes(buf[end + 4:have])
        parts = lines[0].split(" ", 2)
        if len(parts) < 2 or not parts[0].startswith("HTTP/") or len(parts[1]) != 3 or \
                not all("0" <= ch <= "9" for ch in parts[1]):
            raise WireError(f"not an HTTP answer: {lines[0][:80]!r}")
        status = int(parts[1])
        if 100 <= status < 200 and status != 101:  # interim answers (101 would switch protocols: final)
            buf = bytearray(rest) + bytearray(_CHUNK)
            have = len(rest)
            continue
        break
    raw: Dict[str, str] = {}  # (a plain dict while parsing: WireHeaders' lookups lower-case every key)
    cookies: List[str] = []
    last = ""
    for line in lines[1:]:
        if line[:1] in (" ", "\t") and last:  # an obsolete folded line continues the last header
            raw[last] = f"{raw[last]} {line.strip()}"
            continue
        k, sep, v = line.partition(":")
        if not sep:
            continue
        k, v = k.strip().lower(), v.strip()
        if k == "set-cookie":
            cookies.append(v)
        raw[k] = f"{raw[k]}, {v}" if k in raw else v
        last = k
    hdrs = WireHeaders(raw)
    version_10 = parts[0] == "HTTP/1.0"
    conn = hdrs.get("connection", "").lower()
    keep = "keep-alive" in conn if version_10 else "close" not in conn
    content: Union[bytes, bytearray]
    if method == "HEAD" or status in (204, 304):
        content = b""
    elif "chunked" in hdrs.get("transfer-encoding", "").lower():
        content, clean = _read_chunked(sock, rest)
        keep = keep and clean
    elif "content-length" in hdrs:
        values = {v.strip() for v in hdrs["content-length"].split(",")}  # the same value twice is one
        n = int(next(iter(values))) if len(values) == 1 and next(iter(values)).isdigit() else -1
        if n < 0:  # (digits only: int() would take "+5", "-5", "5_0")
            raise WireError(f"a bad Content-Length: {hdrs['content-length']!r}")
        content = bytearray(n)
        got = min(n, len(rest))
        content[:got] = rest[:got]
        if len(rest) > n:  # bytes past the answer: the connection's state is unknown
            keep = False
        view = memoryview(content)
        while got < n:
            got += _recv_into(sock, view[got:])
    else:  # delimited by the connection's end
        chunks = [rest]
        while True:
            piece = sock.recv(_CHUNK)
            if not piece:
                break
            chunks.append(piece)
        content = b"".join(chunks)
        keep = False
    coding = hdrs.get("content-encoding", "identity").lower()
    if content and coding in ("gzip", "x-gzip", "deflate"):
        content = _decode(bytes(content), coding)
    return status, hdrs, content, cookies, keep


def _decode(data: bytes, coding: str) -> bytes:
    """A gzip (every member) or deflate (zlib or raw) body decoded."""
    try:
        if "gzip" in coding:
            out = []
            while data:
                d = zlib.decompressobj(47)
                out.append(d.decompress(data))
                out.append(d.flush())
                data = d.unused_data
            return b"".join(out)
        try:
            return zlib.decompress(data, zlib.MAX_WBITS)
        except zlib.error:
            return zlib.decompress(data, -zlib.MAX_WBITS)  # raw deflate, as some servers send
    except zlib.error as exc:
        raise WireError(f"a {coding} body that does not decode ({exc})") from exc


class _Reader:
    """Bytes of a socket after those already read."""

    def __init__(self, sock: socket.socket, first: bytes) -> None:
        self.sock, self.buf = sock, bytearray(first)

    def line(self) -> bytes:
        while True:
            k = self.buf.find(b"\r\n")
            if k >= 0:
                out = bytes(self.buf[:k])
                del self.buf[:k + 2]
                return out
            if len(self.buf) > _HEAD_LIMIT:
                raise WireError("a chunk's size line longer than 64 kB")
            self._more()

    def take(self, n: int) -> bytes:
        while len(self.buf) < n:
            self._more()
        out = bytes(self.buf[:n])
        del self.buf[:n]
        return out

    def _more(self) -> None:
        piece = self.sock.recv(_CHUNK)
        if not piece:
            raise ConnectionResetError("the peer closed the connection inside a chunked answer")
        self.buf += piece


def _read_chunked(sock: socket.socket, first: bytes) -> Tuple[bytes, bool]:
    r = _Reader(sock, first)
    out = bytearray()
    while True:
        size_line = r.line().split(b";", 1)[0].strip()
        if not size_line or size_line.strip(b"0123456789abcdefABCDEF"):  # (int() would take "-5", "0x5", "5_0")
            raise WireError(f"a bad chunk size: {size_line[:40]!r}")
        size = int(size_line, 16)
        if size == 0:
            while r.line():  # trailers, then the empty line
                pass
            return bytes(out), not r.buf  # (bytes past the answer: the connection's state is unknown)
        out += r.take(size)
        if r.take(2) != b"\r\n":
            raise WireError("a chunk not followed by CRLF")

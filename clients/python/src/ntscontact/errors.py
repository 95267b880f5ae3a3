"""Typed exceptions: every failure of the client or the service maps to one.

``NtsError`` is the base. The service's error documents
(``{"error": {"code", "message", "pointer"}}``, see ``error.schema.json``) keep
their stable ``code`` and JSON ``pointer``; the text a user sees names the body
(by its id, when the scene is at hand) and the node at fault.
"""

from __future__ import annotations

import re
from typing import Any, Mapping, Optional, Sequence

__all__ = [
    "NtsError",
    "InvalidScene",
    "PayloadTooLarge",
    "ServerError",
    "ServiceUnavailable",
    "Timeout",
    "RequestRejected",
    "TLSError",
    "describe_pointer",
]


class NtsError(Exception):
    """Base of every error raised by :mod:`ntscontact`.

    ``status`` is the HTTP status (``None`` when no response was received),
    ``code`` the service's stable error code, ``pointer`` a JSON pointer into the
    request ("" when the error concerns the whole request).
    """

    def __init__(
        self,
        message: str,
        *,
        code: str = "error",
        pointer: str = "",
        status: Optional[int] = None,
        where: str = "",
    ) -> None:
        self.message = message
        self.code = code
        self.pointer = pointer
        self.status = status
        self.where = where
        super().__init__(self._render())

    def _render(self) -> str:
        text = f"{self.code}: {self.message}" if self.code else self.message
        if self.where and self.where not in self.message:
            text += f" ({self.where})"
        elif self.pointer and self.pointer not in text:
            text += f" (at {self.pointer})"
        if self.status is not None:
            text = f"[HTTP {self.status}] {text}"
        return text


class InvalidScene(NtsError, ValueError):
    """The scene was rejected (HTTP 400, or the client's own checks before sending).

    Also a :class:`ValueError`, so code that validates input generically catches it.
    """


class PayloadTooLarge(NtsError):
    """HTTP 413: the request body exceeds the daemon's ``--max-bytes``."""


class ServerError(NtsError):
    """HTTP 5xx other than 503: a bug in the service, or a reply that is not JSON."""


class ServiceUnavailable(NtsError):
    """HTTP 503 (overloaded), or the service could not be reached after the retries."""


class Timeout(NtsError, TimeoutError):
    """No complete answer within the client's timeout (connect or read)."""


class TLSError(NtsError):
    """The TLS handshake with an https daemon failed: most often its certificate
    is not one the client trusts (give it, or its CA, as ``verify=`` /
    ``--ca``), or the URL says https to a plain-HTTP daemon."""


def tls_error(method: str, url: str, exc: BaseException) -> "TLSError":
    """The error of a failed TLS handshake, saying what to check."""
    return TLSError(f"{method} {url}: TLS failed ({exc}); check that the daemon serves https there and that its "
                    "certificate or CA is the one given (verify= / --ca)", code="tls_failed")


class RequestRejected(NtsError):
    """Any other 4xx (404 unknown path, 405 method, 415 content type)."""


_POINTER_BODY = re.compile(r"^/bodies/(\d+)(?:/(nodes|loops|triangles|surface|id)(?:/(\d+)(?:/(\d+))?)?)?")


def _unescape(token: str) -> str:
    return token.replace("~1", "/").replace("~0", "~")


def describe_pointer(pointer: str, bodies: Optional[Sequence[Any]] = None) -> str:
    """A human reading of a JSON pointer: ``/bodies/3/nodes/17`` becomes
    ``body 'cell-7' (index 3), node 17``. ``bodies`` (the scene's body ids, in order)
    lets the body be named by its id."""
    m = _POINTER_BODY.match(pointer or "")
    if not m:
        if pointer and pointer.startswith("/options/"):
            return "option " + _unescape(pointer[len("/options/"):])
        return ""
    index = int(m.group(1))
    name = f"body {index}"
    if bodies is not None and 0 <= index < len(bodies):
        name = f"body {bodies[index]!r} (index {index})"
    field, a, b = m.group(2), m.group(3), m.group(4)
    if field == "nodes" and a is not None:
        return f"{name}, node {a}"
    if field == "loops" and a is not None:
        return f"{name}, loop {a}" + (f", position {b}" if b is not None else "")
    if field == "triangles" and a is not None:
        return f"{name}, triangle {a}"
    if field == "surface":
        return f"{name}, surface" + (f" pair {a}" if a is not None else "")
    if field == "id":
        return f"{name}, id"
    return name


def error_from_response(
    status: int,
    document: Optional[Mapping[str, Any]],
    fallback_text: str = "",
    bodies: Optional[Sequence[Any]] = None,
) -> NtsError:
    """Map an HTTP error response (status and parsed error document) to an exception."""
    err: Mapping[str, Any] = {}
    if isinstance(document, Mapping) and isinstance(document.get("error"), Mapping):
        err = document["error"]
    code = str(err.get("code", "http_%d" % status))
    message = str(err.get("message", fallback_text.strip()[:500] or "HTTP %d" % status))
    pointer = str(err.get("pointer", "") or "")
    where = describe_pointer(pointer, bodies)
    cls: type = RequestRejected
    if status == 413:
        cls = PayloadTooLarge
    elif status == 503:
        cls = ServiceUnavailable
    elif status >= 500:
        cls = ServerError
    elif status in (400, 422):
        cls = InvalidScene
    exc: NtsError = cls(message, code=code, pointer=pointer, status=status, where=where)
    return exc

"""ntscontact: Python client of the 2D node-to-segment contact service.

>>> import numpy as np, ntscontact
>>> scene = ntscontact.Scene(penalty=100.0, alpha=0.2, search_radius=0.1)
>>> scene.add_body(np.array([[0, 0], [1, 0], [1, 1], [0, 1]]), id="a")   # doctest: +SKIP
>>> with ntscontact.Client("http://127.0.0.1:8080") as client:           # doctest: +SKIP
...     result = client.contact(scene, outputs=["forces", "energy", "contacts"])
...     result.forces["a"]                                               # (4, 2) float64
"""

__version__ = "0.3.0"

from .errors import (  # noqa: E402
    InvalidScene,
    NtsError,
    PayloadTooLarge,
    RequestRejected,
    ServerError,
    ServiceUnavailable,
    Timeout,
    TLSError,
)
from .result import Contact, Gap, IncompleteResultWarning, Result, ResultWarning, Summary  # noqa: E402
from .scene import OUTPUTS, SOLVERS, Body, BodyId, Scene  # noqa: E402
from .session import Session  # noqa: E402
from .plot import plot  # noqa: E402
from .client import DEFAULT_URL, USER_AGENT, Client  # noqa: E402
from .engine import Engine, EngineSession, EngineUnavailable  # noqa: E402

__all__ = [
    "__version__",
    "Client",
    "Engine",
    "EngineSession",
    "EngineUnavailable",
    "Session",
    "plot",
    "DEFAULT_URL",
    "USER_AGENT",
    "Scene",
    "Body",
    "BodyId",
    "OUTPUTS",
    "SOLVERS",
    "Result",
    "Summary",
    "Contact",
    "Gap",
    "ResultWarning",
    "IncompleteResultWarning",
    "NtsError",
    "InvalidScene",
    "PayloadTooLarge",
    "ServerError",
    "ServiceUnavailable",
    "Timeout",
    "RequestRejected",
    "TLSError",
]

"""Command line: ``python -m ntscontact convert mesh.msh -o scene.json`` and friends.

Exit codes follow the C CLI: 0 done, 2 usage, 3 invalid input, 1 other failure.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from typing import TYPE_CHECKING, List, Optional

from . import __version__
from .errors import InvalidScene, NtsError
from .scene import OUTPUTS

if TYPE_CHECKING:
    from .client import Client


def _convert(args: argparse.Namespace) -> int:
    from .mesh import scene_from_mesh

    if args.other_bodies != "whole" and not args.surface:
        print("ntscontact: --other-bodies needs --surface", file=sys.stderr)
        return 2
    periodic = tuple(args.periodic) if args.periodic else None
    tag = False if args.no_tags else args.tag
    try:
        scene = scene_from_mesh(args.mesh, penalty=args.penalty, alpha=args.alpha, search_radius=args.search_radius,
                                periodic=periodic, solver=args.solver, outputs=args.outputs, tag=tag,
                                boundary="loops" if args.loops else "triangles",
                                penalty_scaling=args.penalty_scaling, surfaces=args.surface,
                                other_bodies=args.other_bodies)
    except OSError as exc:  # the file cannot be opened: a usage error, as in the C CLI
        print(f"ntscontact: cannot open '{args.mesh}': {exc.strerror or exc}", file=sys.stderr)
        return 2
    text = scene.to_json(indent=2 if args.pretty else None) + "\n"
    if args.output in (None, "-"):
        sys.stdout.write(text)
    else:
        with open(args.output, "w", encoding="utf-8") as fh:
            fh.write(text)
    nodes = sum(b.node_count for b in scene)
    print(f"convert: {len(scene)} bodies, {nodes} nodes from {args.mesh}", file=sys.stderr)
    if args.surface:
        named = [f"{b.id!r} {len(b.surface)} segments" for b in scene if b.surface is not None and len(b.surface)]
        rest = [repr(b.id) for b in scene if b.surface is None]
        off = [repr(b.id) for b in scene if b.surface is not None and not len(b.surface)]
        told = "; ".join(part for part in (
            "contact surfaces: " + ", ".join(named),
            "whole boundary: " + ", ".join(rest) if rest else "",
            "no surface: " + ", ".join(off) if off else "") if part)
        print(f"convert: {told}", file=sys.stderr)
    return 0


class UsageError(Exception):
    """A command line that cannot run as given (exit 2, as the C CLI's usage errors)."""


def read_token_file(path: str) -> str:
    """The token in a file of the daemon's --token-file form: its first line
    that is neither empty nor a ``#`` comment. Raises :class:`UsageError` naming
    the file when it cannot be read or holds none."""
    try:
        with open(path, encoding="utf-8") as fh:
            lines = fh.read().splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise UsageError(f"--token-file {path}: cannot read it ({exc})") from exc
    for line in lines:
        token = line.strip()
        if token and not token.startswith("#"):
            return token
    raise UsageError(f"--token-file {path}: no token in it (one a line; # starts a comment)")


def _client(args: argparse.Namespace) -> "Client":
    """The Client of the command's --url, --timeout, --token/--token-file and --ca."""
    from .client import Client

    if args.token is not None and args.token_file:
        raise UsageError("give --token or --token-file, not both")
    token = read_token_file(args.token_file) if args.token_file else args.token
    if token is None:
        token = os.environ.get("NTSCONTACT_TOKEN") or None
    if args.ca and not os.path.isfile(args.ca):
        raise UsageError(f"--ca {args.ca}: no such file")
    return Client(args.url, timeout=args.timeout, token=token, verify=args.ca if args.ca else True)


def _contact(args: argparse.Namespace) -> int:
    from .scene import Scene

    if args.threads and not args.engine:
        raise UsageError("--threads is for --engine (a daemon has its own --threads)")
    try:
        with open(args.scene, "rb") if args.scene != "-" else sys.stdin.buffer as fh:
            text = fh.read()
    except OSError as exc:  # as in the C CLI: a file that cannot be opened is a usage error
        raise UsageError(f"cannot open '{args.scene}': {exc.strerror or exc}") from exc
    scene = Scene.from_json(text)
    if args.engine:  # in process, no daemon
        from .engine import Engine

        with Engine(threads=args.threads) as engine:
            result = engine.contact(scene, outputs=args.outputs)
    else:
        with _client(args) as client:
            result = client.contact(scene, outputs=args.outputs)
    json.dump(result.raw, sys.stdout, indent=2 if args.pretty else None)
    sys.stdout.write("\n")
    return 0


def _health(args: argparse.Namespace) -> int:
    with _client(args) as client:
        json.dump(client.health(), sys.stdout, indent=2)
    sys.stdout.write("\n")
    return 0


def _engine(args: argparse.Namespace) -> int:
    """Where the in-process engine's library is, or why there is none."""
    from .engine import Engine, EngineUnavailable

    try:
        with Engine() as engine:
            print(f"engine: {engine.library}")
    except EngineUnavailable as exc:
        print(f"engine: none: {exc.message}")
        return 1
    return 0


def _threads(text: str) -> int:
    """An evaluation's thread count for argparse: an integer in [0, 1024]."""
    try:
        n = int(text)
    except ValueError:
        n = -1
    if not 0 <= n <= 1024:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer in [0, 1024]")
    return n


def _remote(p: argparse.ArgumentParser, timeout: float) -> None:
    """The options of a command that talks to a daemon."""
    p.add_argument("--url", default="http://127.0.0.1:8080")
    p.add_argument("--timeout", type=float, default=timeout, help="seconds (default %(default)s)")
    p.add_argument("--token", help="bearer token of the daemon's --token-file (default: $NTSCONTACT_TOKEN); "
                                   "--token-file keeps it off the command line")
    p.add_argument("--token-file", metavar="FILE", help="read the bearer token from FILE")
    p.add_argument("--ca", metavar="FILE", help="for https: the daemon's certificate, or the CA that signed it "
                                                "(default: the system's CAs)")


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``python -m ntscontact`` (subcommands convert, contact, health)."""
    p = argparse.ArgumentParser(prog="python -m ntscontact", description="ntscontact Python tools")
    p.add_argument("--version", action="version", version=f"ntscontact-python {__version__}")
    sub = p.add_subparsers(dest="command", required=True)

    c = sub.add_parser("convert", help="mesh file (any format meshio reads) to a scene JSON")
    c.add_argument("mesh", help="mesh file: .msh, .vtk, .vtu, .xdmf, .med, ...")
    c.add_argument("-o", "--output", help="scene JSON file (default: standard output)")
    c.add_argument("--penalty", type=float, required=True, metavar="EPS",
                   help="options.penalty, the penalty stiffness (required: no default fits every scale; "
                        "docs/coupling.md says how to choose it)")
    c.add_argument("--alpha", type=float, help="options.alpha")
    c.add_argument("--search-radius", type=float, help="options.search_radius")
    c.add_argument("--periodic", type=float, nargs=2, metavar=("LX", "LY"), help="periodic box")
    c.add_argument("--solver", choices=("closed_form", "newton"))
    c.add_argument("--outputs", help="comma-separated: " + ",".join(OUTPUTS))
    c.add_argument("--penalty-scaling", choices=("node", "length"),
                   help="options.penalty_scaling (length: a node's force is eps g times its tributary length)")
    c.add_argument("--surface", action="append", metavar="NAME",
                   help="a gmsh physical curve (1D physical group, by name) whose line elements make the contact "
                        "surface of the body that owns them (repeat for several: their union)")
    c.add_argument("--other-bodies", choices=("whole", "none"), default="whole",
                   help="with --surface, what a body that owns none of the named curves gets: whole (default: its "
                        "whole boundary) or none (it takes part in nothing)")
    c.add_argument("--tag", help="cell_data field naming the body of each cell (default: gmsh:physical if present)")
    c.add_argument("--no-tags", action="store_true", help="ignore tags: bodies are connected components")
    c.add_argument("--loops", action="store_true", help="write boundary loops instead of triangles")
    c.add_argument("--pretty", action="store_true")
    c.set_defaults(func=_convert)

    q = sub.add_parser("contact", help="evaluate a scene JSON on a running ntscontactd (or in process: --engine)")
    q.add_argument("scene", help="scene JSON file, or - for standard input")
    _remote(q, 30.0)
    q.add_argument("--engine", action="store_true", help="evaluate in process (ntscontact.Engine), no daemon")
    q.add_argument("--threads", type=_threads, default=0, help="with --engine: evaluation threads (0: serial)")
    q.add_argument("--outputs", help="comma-separated outputs")
    q.add_argument("--pretty", action="store_true")
    q.set_defaults(func=_contact)

    h = sub.add_parser("health", help="GET /v1/health of a running ntscontactd")
    _remote(h, 5.0)
    h.set_defaults(func=_health)

    e = sub.add_parser("engine", help="where the in-process engine's library is (exit 1: none, and how to get it)")
    e.set_defaults(func=_engine)
    return p


def main(argv: Optional[List[str]] = None) -> int:
    """Run the command line on ``argv`` (default: ``sys.argv[1:]``) and return its exit code."""
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args))
    except BrokenPipeError:
        # the reader left (`... | head`): quietly, as a C tool killed by
        # SIGPIPE; stdout pointed at /dev/null so that the interpreter's own
        # flush at exit does not complain either
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141
    except UsageError as exc:
        print(f"ntscontact: {exc}", file=sys.stderr)
        return 2
    except InvalidScene as exc:
        print(f"ntscontact: {exc}", file=sys.stderr)
        return 3
    except (NtsError, OSError, KeyError) as exc:
        print(f"ntscontact: {exc}", file=sys.stderr)
        return 1
    except ImportError as exc:
        print(f"ntscontact: {exc}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())

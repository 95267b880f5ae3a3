#!/usr/bin/env python3
"""The project's version, written once in VERSION.

CMake reads VERSION itself (project(), hence NTS_VERSION_STRING in C, the CLI's
and the daemon's --version, /v1/health). The copies that cannot read a file at
run time are written from it here: the Python package's __version__, the
OpenAPI document's info.version, CITATION.cff's version and date, and the
User-Agent named in docs/python.md.

    scripts/version.py            check every copy against VERSION (exit 1 on a difference)
    scripts/version.py 0.4.0      set VERSION and write every copy (CITATION.cff dated today)
"""
import datetime
import json
import pathlib
import re
import sys

REPO = pathlib.Path(__file__).resolve().parents[1]

# (file, pattern whose group 1 is the version). One row per copy.
COPIES = [
    ("clients/python/src/ntscontact/__init__.py", r'^__version__ = "([^"]+)"$'),
    ("schemas/openapi.json", r'^    "version": "([^"]+)",$'),
    ("CITATION.cff", r'^version: "([^"]+)"$'),
    ("docs/python.md", r"User-Agent `ntscontact-python/([0-9][^`]*)`"),
]


def read_version():
    return (REPO / "VERSION").read_text().strip()


def check(version):
    bad = []
    for path, pattern in COPIES:
        m = re.search(pattern, (REPO / path).read_text(), re.M)
        if m is None or m.group(1) != version:
            bad.append(f"{path}: {m.group(1) if m else 'no version found'} (VERSION: {version})")
    # the OpenAPI copy is the document's info.version, not some other "version"
    if json.loads((REPO / "schemas/openapi.json").read_text())["info"]["version"] != version:
        bad.append("schemas/openapi.json: info.version differs")
    return bad


def write(version):
    if not re.fullmatch(r"[0-9]+\.[0-9]+\.[0-9]+", version):
        sys.exit(f"version.py: {version!r} is not MAJOR.MINOR.PATCH")
    (REPO / "VERSION").write_text(version + "\n")
    for path, pattern in COPIES:
        f = REPO / path
        text = f.read_text()
        m = re.search(pattern, text, re.M)
        if m is None:
            sys.exit(f"version.py: no version in {path}")
        f.write_text(text[:m.start(1)] + version + text[m.end(1):])
    cff = REPO / "CITATION.cff"
    cff.write_text(re.sub(r'^date-released: "[^"]*"$', f'date-released: "{datetime.date.today().isoformat()}"',
                          cff.read_text(), flags=re.M))


def main():
    if len(sys.argv) > 1:
        write(sys.argv[1])
    version = read_version()
    bad = check(version)
    for line in bad:
        print(line, file=sys.stderr)
    if not bad:
        print(version)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())

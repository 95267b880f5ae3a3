"""Shared pytest fixtures: where the repository, the build, the binaries, the
example scenes and the JSON Schemas are. The build directory is $NTS_BUILD_DIR
(default <repo>/build). Keep this file small and generic; append fixtures."""
import json
import os
import pathlib
import types

import pytest

REPO = pathlib.Path(__file__).resolve().parents[2]
BUILD = pathlib.Path(os.environ.get("NTS_BUILD_DIR", str(REPO / "build"))).resolve()


@pytest.fixture(scope="session")
def paths():
    """paths.repo, .build, .bin, .cli (build/bin/ntscontact), .examples, .schemas."""
    return types.SimpleNamespace(
        repo=REPO,
        build=BUILD,
        bin=BUILD / "bin",
        cli=BUILD / "bin" / "ntscontact",
        examples=REPO / "examples",
        schemas=REPO / "schemas",
    )


@pytest.fixture(scope="session")
def schemas(paths):
    """The JSON Schemas by short name: schemas["scene"], ["result"], ["error"]."""
    return {name: json.loads((paths.schemas / f"{name}.schema.json").read_text())
            for name in ("scene", "result", "error")}

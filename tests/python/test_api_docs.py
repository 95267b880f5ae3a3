"""The API reference is generated from the sources and leaves nothing out
(issue 28): Doxygen on the public C headers (docs/api/Doxyfile) warns about
nothing, sees every declared function, and does warn about an undocumented
function or struct (a control, so the check can fail); every public module,
class, function and method of the Python package has a docstring (with a
control on a synthetic package); pdoc builds the Python reference.
scripts/docs.sh builds both into build/docs."""
import importlib
import inspect
import os
import pathlib
import pkgutil
import re
import shutil
import subprocess
import sys

import pytest

from conftest import REPO

DOXYFILE = REPO / "docs" / "api" / "Doxyfile"
PUBLIC_HEADERS = sorted([*(REPO / "core" / "include" / "ntscontact").glob("*.h"),
                         *(REPO / "codec" / "include" / "ntscontact").glob("*.h"),
                         *(REPO / "mpi" / "include" / "ntscontact").glob("*.h")])
PY_SRC = REPO / "clients" / "python" / "src"


# ------------------------------------------------------------------ C (Doxygen)

def doxygen(out, **settings):
    """Doxygen with docs/api/Doxyfile plus `settings` (later lines win), run
    from the repository's root as scripts/docs.sh runs it, writing into `out`:
    (the completed process, the warning log's text)."""
    if shutil.which("doxygen") is None:
        pytest.skip("doxygen is not installed (scripts/install-deps.sh installs Debian's package)")
    out.mkdir(parents=True, exist_ok=True)
    log = out / "warnings.log"
    settings = {"OUTPUT_DIRECTORY": f'"{out}"', "WARN_LOGFILE": f'"{log}"', **settings}
    config = DOXYFILE.read_text() + "".join(f"\n{k} = {v}" for k, v in settings.items()) + "\n"
    run = subprocess.run(["doxygen", "-"], input=config, cwd=REPO, capture_output=True, text=True, timeout=300)
    return run, log.read_text() if log.exists() else ""


def declared_functions(header):
    """The functions a header declares for users: NTS_API ones and static inline ones."""
    text = re.sub(r"/\*.*?\*/", " ", header.read_text(), flags=re.S)  # not the names comments mention
    text = "\n".join(line for line in text.splitlines() if not line.lstrip().startswith("#"))
    return re.findall(r"\b(?:NTS_API|static\s+inline)\b[^;{(]*?\b(\w+)\s*\(", text)


def doxyfile_inputs():
    m = re.search(r"(?m)^INPUT\s*=((?:.*\\\n)*.*)$", DOXYFILE.read_text())
    assert m, "docs/api/Doxyfile has no INPUT"
    return sorted(REPO / p for p in m.group(1).replace("\\\n", " ").split())


def test_the_doxyfile_reads_every_public_header():
    assert len(PUBLIC_HEADERS) >= 6, PUBLIC_HEADERS
    assert doxyfile_inputs() == PUBLIC_HEADERS, "docs/api/Doxyfile's INPUT is not the public headers"


def test_doxygen_documents_every_public_declaration(tmp_path):
    run, warnings = doxygen(tmp_path / "c")
    assert warnings == "", f"undocumented or badly documented public C API:\n{warnings}"
    assert run.returncode == 0, run.stderr
    html = tmp_path / "c" / "html"
    assert (html / "index.html").is_file()
    # Every declared function has its entry (a declaration Doxygen misparsed,
    # say an NTS_API it could not see through, would be missing, not warned of).
    pages = "".join(p.read_text(errors="replace") for p in html.glob("*_8h.html"))
    names = [n for h in PUBLIC_HEADERS for n in declared_functions(h)]
    assert len(names) > 100 and "nts_evaluate" in names and "ntsj_handle" in names, len(names)
    missing = [n for n in names if not re.search(rf"\b{n}\b", pages)]
    assert not missing, f"the C reference lacks {missing}"


def test_doxygen_fails_on_an_undocumented_function_or_struct(tmp_path):
    """The control: the same configuration on a public header with one
    undocumented function and one undocumented struct added."""
    text = (REPO / "core" / "include" / "ntscontact" / "base.h").read_text()
    probe = ("NTS_API int nts_undocumented_probe(void);\n"
             "typedef struct nts_undocumented_struct { int field; } nts_undocumented_struct;\n")
    tail = text.rindex("#ifdef __cplusplus")  # before the closing of extern "C"
    header = tmp_path / "probe.h"
    header.write_text(text[:tail] + probe + text[tail:])
    run, warnings = doxygen(tmp_path / "c", INPUT=f'"{header}"')
    assert "nts_undocumented_probe" in warnings, warnings
    assert "nts_undocumented_struct" in warnings, warnings
    assert run.returncode != 0  # WARN_AS_ERROR: a warning fails the run


# -------------------------------------------------------------- Python (pdoc)

def public_modules(package):
    """The package and its submodules whose names have no part starting with '_'."""
    pkg = importlib.import_module(package)
    names = [m.name for m in pkgutil.walk_packages(pkg.__path__, package + ".")
             if not any(part.startswith("_") for part in m.name.split("."))]
    return [pkg] + [importlib.import_module(n) for n in sorted(names)]


def own_class_doc(cls):
    """The class's own docstring: not one it inherits, nor the signature a
    dataclass or a namedtuple writes for a class that has none."""
    doc = (cls.__dict__.get("__doc__") or "").strip()
    if doc.startswith(cls.__name__ + "(") or any(doc == (b.__doc__ or "").strip() for b in cls.__mro__[1:]):
        return ""
    return doc


def public_api(package):
    """(kind, qualified name, docstring) of every public module, class,
    function and method (properties included) of `package`: a module's names
    are its __all__, or else those not starting with '_'; a class or function
    counts once, in the module that defines it."""
    seen, out = set(), []
    for mod in public_modules(package):
        out.append(("module", mod.__name__, (mod.__doc__ or "").strip()))
        names = getattr(mod, "__all__", None) or [n for n in vars(mod) if not n.startswith("_")]
        for name in names:
            obj = getattr(mod, name)
            if not (inspect.isclass(obj) or inspect.isfunction(obj)) or id(obj) in seen:
                continue
            if not getattr(obj, "__module__", "").startswith(package):  # imported from elsewhere
                continue
            seen.add(id(obj))
            where = f"{obj.__module__}.{obj.__qualname__}"
            if inspect.isfunction(obj):
                out.append(("function", where, (obj.__doc__ or "").strip()))
                continue
            out.append(("class", where, own_class_doc(obj)))
            for member, value in vars(obj).items():
                if member.startswith("_"):
                    continue
                if isinstance(value, (staticmethod, classmethod)):
                    value = value.__func__
                if isinstance(value, property) or inspect.isfunction(value):
                    out.append(("method", f"{where}.{member}", (inspect.getdoc(value) or "").strip()))
    return out


def undocumented(package):
    return [f"{kind} {name}" for kind, name, doc in public_api(package) if not doc]


def test_every_public_python_name_has_a_docstring():
    ntscontact = pytest.importorskip("ntscontact")
    here = pathlib.Path(ntscontact.__file__).resolve()
    assert here.is_relative_to(PY_SRC), f"ntscontact comes from {here}, not this checkout (PYTHONPATH={PY_SRC})"
    api = public_api("ntscontact")
    names = {name for _, name, _ in api}
    # the walk reaches the classes, their methods and properties, and the submodules
    for name in ("ntscontact.client.Client", "ntscontact.client.Client.contact", "ntscontact.scene.Scene.from_json",
                 "ntscontact.result.Result.energy", "ntscontact.mesh", "ntscontact.plot.plot"):
        assert name in names, name
    missing = undocumented("ntscontact")
    assert not missing, f"public Python API without a docstring: {missing}"


def test_the_docstring_check_finds_what_lacks_one(tmp_path, monkeypatch):
    """The control: a synthetic package with one of each kind undocumented."""
    pkg = tmp_path / "nts_probe_pkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text('"""A probe package."""\nfrom .mod import Documented, bare\n'
                                     '__all__ = ["Documented", "bare"]\n')
    (pkg / "mod.py").write_text('''\
"""Documented module."""
import dataclasses
from typing import Optional  # imported: not this package's to document


def bare():
    return 1


def _private():
    return 2


class Documented:
    """A class."""

    def fine(self):
        """A method."""

    def naked(self):
        return 3

    @property
    def prop(self):
        return 4

    @classmethod
    def make(cls):
        return cls()

    def _hidden(self):
        return 5


@dataclasses.dataclass
class Record:
    x: int


class Error(ValueError):
    pass
''')
    (pkg / "_internal.py").write_text("def undocumented_but_private():\n    return 6\n")
    (pkg / "nodoc.py").write_text("X = 1\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    try:
        assert sorted(undocumented("nts_probe_pkg")) == [
            "class nts_probe_pkg.mod.Error",
            "class nts_probe_pkg.mod.Record",
            "function nts_probe_pkg.mod.bare",
            "method nts_probe_pkg.mod.Documented.make",
            "method nts_probe_pkg.mod.Documented.naked",
            "method nts_probe_pkg.mod.Documented.prop",
            "module nts_probe_pkg.nodoc",
        ]
    finally:
        for name in [n for n in sys.modules if n.split(".")[0] == "nts_probe_pkg"]:
            del sys.modules[name]


def test_pdoc_builds_the_python_reference(tmp_path):
    """pdoc, given the package and its public modules as scripts/docs.sh gives
    them (the package's __all__ leaves its submodules out), writes a page for each."""
    pytest.importorskip("pdoc", reason="pdoc is in requirements-dev.txt (scripts/install-deps.sh)")
    modules = sorted(m.name for m in pkgutil.iter_modules([str(PY_SRC / "ntscontact")]) if not m.name.startswith("_"))
    assert {"client", "scene", "result", "session", "mesh"} <= set(modules), modules
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(PY_SRC), os.environ.get("PYTHONPATH", "")])}
    out = tmp_path / "python"
    run = subprocess.run([sys.executable, "-W", "ignore:The module specification", "-m", "pdoc", "--docformat", "restructuredtext", "-o", str(out),
                          "ntscontact", *(f"ntscontact.{m}" for m in modules)],
                         env=env, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    assert (out / "index.html").is_file()
    page = (out / "ntscontact.html").read_text()
    assert "Client" in page and "Scene" in page
    missing = [m for m in modules if not (out / "ntscontact" / f"{m}.html").is_file()]
    assert not missing, f"pdoc wrote no page for {missing}"
    # a docstring added for this reference shows in it
    assert "A scene from JSON text" in (out / "ntscontact" / "scene.html").read_text()

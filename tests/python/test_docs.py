"""The docs say what the tools do (issue 22, section 6, "Stale docs"): the
README's CLI section names every option of `ntscontact --help` and every
output; its Python section the client's sessions, tangent, VTK and plots;
docs/python.md every parameter and method of `Client`; the README or
docs/operations.md every option of `ntscontactd --help`; the docs cite only
files that exist and no machine's absolute paths; the C example the README
links builds, runs and says what it is."""
import inspect
import json
import re
import subprocess

import pytest

from conftest import BUILD, REPO

DOCS = [REPO / "README.md", *sorted((REPO / "docs").glob("*.md")), REPO / "deploy" / "README.md",
        REPO / "clients" / "python" / "README.md", REPO / "bench" / "README.md"]


def section(text, title):
    """The Markdown section under the heading `title` (to the next heading of its level or higher)."""
    m = re.search(rf"(?m)^(#+) {re.escape(title)}\s*$", text)
    assert m, f"no section {title!r}"
    level = len(m.group(1))
    rest = text[m.end():]
    end = re.search(rf"(?m)^#{{1,{level}}} ", rest)
    return rest[:end.start()] if end else rest


def help_long_options(binary):
    text = subprocess.run([str(binary), "--help"], capture_output=True, text=True, timeout=30).stdout
    return sorted({o for line in text.splitlines() if line.startswith("  -")
                   for o in re.findall(r"(?:^ {2}|, )(--[a-z][a-z-]*)", line)} - {"--help", "--version"})


def test_readme_cli_section_names_every_option_and_output(schemas):
    cli = section((REPO / "README.md").read_text(), "The command-line tool")
    missing = [o for o in help_long_options(BUILD / "bin" / "ntscontact") if not re.search(rf"{o}(?![a-z-])", cli)]
    assert not missing, f"README's CLI section lacks {missing}"
    names = schemas["scene"]["$defs"]["output"]["enum"]  # every output (tables.h's NTS_OUTPUT_MAP)
    assert "stiffness" in names and "pressure" in names
    assert not [n for n in names if n not in cli], names


def test_readme_or_operations_names_every_daemon_option():
    text = section((REPO / "README.md").read_text(), "The HTTP service") + (REPO / "docs" / "operations.md").read_text()
    missing = [o for o in help_long_options(BUILD / "bin" / "ntscontactd") if not re.search(rf"{o}(?![a-z-])", text)]
    assert not missing, f"neither the README's HTTP section nor docs/operations.md names {missing}"


def test_readme_python_section_names_the_clients_features():
    ntscontact = pytest.importorskip("ntscontact")
    py = section((REPO / "README.md").read_text(), "The Python client")
    # the features, by the names a user calls
    for name in ("Client", "Scene", "Session", "session(", "stiffness", "to_vtk", "plot(", "convert", "token="):
        assert name in py, f"README's Python section lacks {name!r}"
    assert hasattr(ntscontact.Client, "session") and hasattr(ntscontact.Result, "to_vtk")
    assert hasattr(ntscontact.Result, "stiffness") and callable(ntscontact.plot)


def test_python_doc_names_every_client_parameter_and_method():
    ntscontact = pytest.importorskip("ntscontact")
    doc = section((REPO / "docs" / "python.md").read_text(), "The client")
    params = [p for p in inspect.signature(ntscontact.Client.__init__).parameters if p != "self"]
    methods = [n for n, f in inspect.getmembers(ntscontact.Client, inspect.isfunction) if not n.startswith("_")]
    assert "token" in params and "session" in methods
    missing = [p for p in params if not re.search(rf"\b{p}=", doc)] + [
        m for m in methods if not re.search(rf"\b{m}\(", doc)]
    assert not missing, f"docs/python.md, 'The client', lacks {missing}"
    schemas = sorted(p.name.split(".")[0] for p in (REPO / "schemas").glob("*.schema.json"))
    for name in schemas:  # client.schema(name) for every schema the service serves
        assert f'"{name}"' in doc, name


PATH = re.compile(r"(?<![\w./:-])((?:core|codec|cli|server|clients|schemas|examples|tests|bench|docs|scripts|deploy|"
                  r"support|fuzz|fortran)/[\w./*-]*[\w*])")


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: str(p.relative_to(REPO)))
def test_docs_cite_files_that_exist(doc):
    """Every repository path a document cites exists (a file of an older
    release is cited as `git show REV:path`, which this skips)."""
    missing = []
    for i, line in enumerate(doc.read_text().splitlines(), 1):
        for m in PATH.finditer(line):
            path = m.group(1)
            if not (list(REPO.glob(path)) if "*" in path else (REPO / path).exists()):
                missing.append(f"{doc.name}:{i}: {path}")
    assert not missing, missing


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: str(p.relative_to(REPO)))
def test_docs_hold_no_machine_paths(doc):
    found = re.findall(r"(?<![\w.~-])/(?:work|home|root|tmp|Users|mnt|srv)/[^\s`)'\"]*", doc.read_text())
    assert not found, found


def test_the_c_example_runs_and_the_readme_links_it():
    src = REPO / "core" / "examples" / "two_disks.c"
    readme = (REPO / "README.md").read_text()
    assert "(core/examples/two_disks.c)" in readme  # a Markdown link
    first = re.match(r"\s*/\*(.*?)\*/", src.read_text(), re.S).group(1)
    assert "build/bin/two_disks" in first and "CLI exists" not in first, first
    run = subprocess.run([str(BUILD / "bin" / "two_disks")], capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    m = re.search(r"active contacts (\d+), energy ([0-9.e+-]+)", run.stdout)
    assert m and int(m.group(1)) > 0 and float(m.group(2)) > 0, run.stdout

"""A mesh file given to the C CLI gets a clear error that names what it looks
like and how to convert it (exit 3), never a bare JSON parse error."""
import os
import pathlib
import subprocess

import pytest

REPO = pathlib.Path(__file__).resolve().parents[2]
CLI = pathlib.Path(os.environ.get("NTS_BUILD_DIR", str(REPO / "build"))) / "bin" / "ntscontact"

CASES = [
    ("mesh.msh", b"$MeshFormat\n4.1 0 8\n$EndMeshFormat\n", "a Gmsh mesh"),
    ("data.txt", b"$MeshFormat\n2.2 0 8\n$EndMeshFormat\n", "a Gmsh mesh"),  # by content
    ("mesh.vtk", b"# vtk DataFile Version 4.2\nmesh\nASCII\n", "a legacy VTK file"),
    ("mesh.xml", b'<?xml version="1.0"?>\n<VTKFile type="UnstructuredGrid">\n', "a VTK XML mesh"),
    ("mesh.vtu", b"garbage", "a VTK XML mesh"),  # by extension
    ("mesh.h5", b"\x89HDF\r\n\x1a\n", "an HDF5 file"),
    ("mesh.inp", b"*Heading\n", "an Abaqus mesh"),
    ("mesh.mesh", b"MeshVersionFormatted 2\n", "a Medit mesh"),
]


@pytest.mark.parametrize("name,data,kind", CASES)
def test_mesh_files_are_named_with_the_way_to_convert(tmp_path, name, data, kind):
    path = tmp_path / name
    path.write_bytes(data)
    r = subprocess.run([str(CLI), str(path)], capture_output=True, timeout=30)
    assert r.returncode == 3
    err = r.stderr.decode()
    assert err.startswith('ntscontact: invalid_json at "": ') and kind in err
    assert "python -m ntscontact convert" in err and str(path) in err


def test_a_scene_with_a_mesh_extension_is_still_a_scene(tmp_path):
    path = tmp_path / "scene.msh"
    path.write_bytes((REPO / "examples" / "two_disks.json").read_bytes())
    r = subprocess.run([str(CLI), str(path)], capture_output=True, timeout=30)
    assert r.returncode == 0 and r.stdout.startswith(b'{"version":1')


def test_mesh_on_standard_input(tmp_path):
    r = subprocess.run([str(CLI), "-"], input=b"$MeshFormat\n", capture_output=True, timeout=30)
    assert r.returncode == 3 and b"the input looks like a Gmsh mesh" in r.stderr

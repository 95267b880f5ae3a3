"""`cmake --install` then `find_package(ntscontact)` from the install prefix:
a user's project (tests/cmake/consumer) configures, builds against the core
and the codec, and runs; the same program built through pkg-config alone
(lib/pkgconfig/ntscontact.pc, ntscontact-codec.pc), from a static install
and from a shared one (-DBUILD_SHARED_LIBS=ON), whose installed CLI runs
without LD_LIBRARY_PATH; and, when the build has the Fortran module, a
Fortran program (tests/cmake/fortran_consumer, docs/coupling.md's example)
through ntscontact::fortran."""
import json
import os
import pathlib
import re
import shutil
import subprocess

import pytest

REPO = pathlib.Path(__file__).resolve().parents[2]
VERSION = (REPO / "VERSION").read_text().strip()  # the one source (scripts/version.py)


@pytest.mark.skipif(shutil.which("cmake") is None, reason="needs cmake")
def test_find_package_from_an_install_prefix(paths, tmp_path):
    config = (paths.build / "core" / "generated" / "ntscontact" / "config.h").read_text()
    if "NTS_CONFIG_SANITIZE 1" in config:
        pytest.skip("a sanitizer build: its static libraries need the sanitizer runtime in the consumer too")
    prefix = tmp_path / "prefix"
    subprocess.run(["cmake", "--install", str(paths.build), "--prefix", str(prefix)], check=True,
                   capture_output=True, timeout=120)
    assert (prefix / "include" / "ntscontact" / "ntscontact.h").exists()
    assert (prefix / "include" / "ntscontact" / "config.h").exists()
    assert list(prefix.glob("lib*/cmake/ntscontact/ntscontactConfig.cmake"))
    build = tmp_path / "consumer"
    r = subprocess.run(["cmake", "-S", str(REPO / "tests" / "cmake" / "consumer"), "-B", str(build),
                        f"-DCMAKE_PREFIX_PATH={prefix}"], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stdout + r.stderr
    r = subprocess.run(["cmake", "--build", str(build)], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    out = subprocess.run([str(build / "consumer")], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stdout + out.stderr
    assert f"version {VERSION}" in out.stdout and "contacts " in out.stdout and "codec has energy" in out.stdout
    assert int(out.stdout.split("contacts ")[1].split()[0]) > 0


@pytest.mark.skipif(shutil.which("cmake") is None, reason="needs cmake")
def test_fortran_module_from_an_install_prefix(paths, tmp_path):
    """The installed .mod and ntscontact::fortran: tests/cmake/fortran_consumer
    configures, builds and prints what docs/coupling.md says it prints; the
    program there is this one, verbatim."""
    if not (paths.build / "fortran" / "mod" / "ntscontact.mod").exists():
        pytest.skip("the build has no Fortran module (no Fortran compiler, or NTS_FORTRAN=OFF)")
    if sanitized(paths):
        pytest.skip("a sanitizer build: its static libraries need the sanitizer runtime in the consumer too")
    source = REPO / "tests" / "cmake" / "fortran_consumer"
    program = (source / "main.f90").read_text()
    assert program in (REPO / "docs" / "coupling.md").read_text(), "docs/coupling.md: not the tested program"
    prefix = tmp_path / "prefix"
    subprocess.run(["cmake", "--install", str(paths.build), "--prefix", str(prefix)], check=True,
                   capture_output=True, timeout=120)
    assert (prefix / "include" / "ntscontact" / "fortran" / "ntscontact.mod").exists()
    assert list(prefix.glob("lib*/cmake/ntscontact/ntscontactFortranTargets.cmake"))
    build = tmp_path / "consumer"
    r = subprocess.run(["cmake", "-S", str(source), "-B", str(build), f"-DCMAKE_PREFIX_PATH={prefix}"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stdout + r.stderr
    r = subprocess.run(["cmake", "--build", str(build)], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    out = subprocess.run([str(build / "squares")], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stdout + out.stderr
    block = (REPO / "docs" / "coupling.md").read_text().split("<!-- fortran output -->")[1].split("```")[1]
    shown = block.split("\n", 1)[1]  # past the block's language tag
    assert out.stdout.strip() == shown.strip(), out.stdout


def sanitized(paths):
    config = (paths.build / "core" / "generated" / "ntscontact" / "config.h").read_text()
    return "NTS_CONFIG_SANITIZE 1" in config


def consumer_through_pkg_config(prefix, out, env):
    """tests/cmake/consumer/main.c built with cc and `pkg-config --cflags --libs
    ntscontact-codec` alone (no CMake), from the .pc files of `prefix`."""
    pcdirs = sorted(str(p) for p in prefix.glob("lib*/pkgconfig")) + sorted(
        str(p) for p in prefix.glob("lib/*/pkgconfig"))
    assert pcdirs, list(prefix.rglob("*.pc"))
    env = dict(env, PKG_CONFIG_PATH=":".join(pcdirs))
    flags = subprocess.run(["pkg-config", "--cflags", "--libs", "ntscontact-codec"], capture_output=True, text=True,
                           env=env, timeout=60)
    assert flags.returncode == 0, flags.stderr
    r = subprocess.run(["cc", "-std=c99", "-o", str(out), str(REPO / "tests" / "cmake" / "consumer" / "main.c"),
                        *flags.stdout.split()], capture_output=True, text=True, env=env, timeout=120)
    assert r.returncode == 0, flags.stdout + r.stdout + r.stderr
    return flags.stdout


def check_consumer_output(out):
    assert out.returncode == 0, out.stdout + out.stderr
    assert f"version {VERSION}" in out.stdout and "codec has energy" in out.stdout
    assert int(out.stdout.split("contacts ")[1].split()[0]) > 0


@pytest.mark.skipif(shutil.which("pkg-config") is None or shutil.which("cc") is None, reason="needs pkg-config and cc")
def test_pkg_config_from_a_static_install(paths, tmp_path):
    """The default (static) build: `pkg-config --libs` alone gives a complete
    link line (GSL, libm and OpenMP), and the program needs no libntscontact.so."""
    if sanitized(paths):
        pytest.skip("a sanitizer build: its static libraries need the sanitizer runtime in the consumer too")
    prefix = tmp_path / "prefix"
    subprocess.run(["cmake", "--install", str(paths.build), "--prefix", str(prefix)], check=True,
                   capture_output=True, timeout=120)
    env = {k: v for k, v in os.environ.items() if k not in ("LD_LIBRARY_PATH", "PKG_CONFIG_PATH")}
    flags = consumer_through_pkg_config(prefix, tmp_path / "consumer", env)
    assert "-lgsl" in flags and "-lm" in flags
    if "NTS_CONFIG_OPENMP 1" in (prefix / "include" / "ntscontact" / "config.h").read_text():
        assert "-fopenmp" in flags or "omp" in flags
    check_consumer_output(subprocess.run([str(tmp_path / "consumer")], capture_output=True, text=True, env=env,
                                         timeout=60))
    ldd = subprocess.run(["ldd", str(tmp_path / "consumer")], capture_output=True, text=True, timeout=60)
    assert "libntscontact" not in ldd.stdout


@pytest.mark.skipif(shutil.which("cmake") is None or shutil.which("pkg-config") is None, reason="needs cmake, pkg-config")
def test_shared_build_installs_programs_that_run(paths, tmp_path):
    """-DBUILD_SHARED_LIBS=ON: the installed CLI finds libntscontact.so.0
    (relative RPATH) with no LD_LIBRARY_PATH, even once the prefix is moved;
    a consumer builds through pkg-config and links the shared core."""
    if sanitized(paths):
        pytest.skip("built once, in the normal test run")
    build, prefix = tmp_path / "build", tmp_path / "prefix"
    r = subprocess.run(["cmake", "-S", str(REPO), "-B", str(build), "-DBUILD_SHARED_LIBS=ON", "-DNTS_BUILD_TESTS=OFF",
                        "-DNTS_COMPONENTS=codec;cli", "-DCMAKE_BUILD_TYPE=RelWithDebInfo"], capture_output=True,
                       text=True, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    r = subprocess.run(["cmake", "--build", str(build), "-j", "2"], capture_output=True, text=True, timeout=900)
    assert r.returncode == 0, r.stdout + r.stderr
    r = subprocess.run(["cmake", "--install", str(build), "--prefix", str(prefix)], capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 0, r.stdout + r.stderr
    assert list(prefix.glob("lib*/libntscontact.so.0"))
    moved = tmp_path / "elsewhere"
    shutil.move(str(prefix), str(moved))
    shutil.rmtree(build)  # nothing may come from the build tree
    env = {k: v for k, v in os.environ.items() if k not in ("LD_LIBRARY_PATH", "PKG_CONFIG_PATH")}
    cli = subprocess.run([str(moved / "bin" / "ntscontact"), str(REPO / "examples" / "two_disks.json")],
                         capture_output=True, text=True, env=env, timeout=60)
    assert cli.returncode == 0, cli.stderr
    assert json.loads(cli.stdout)["summary"]["contacts"] > 0
    flags = consumer_through_pkg_config(moved, tmp_path / "consumer", env)
    assert "-lntscontact" in flags
    libdir = next(moved.glob("lib*/libntscontact.so.0")).parent
    out = subprocess.run([str(tmp_path / "consumer")], capture_output=True, text=True, timeout=60,
                         env=dict(env, LD_LIBRARY_PATH=str(libdir)))
    check_consumer_output(out)
    ldd = subprocess.run(["ldd", str(tmp_path / "consumer")], capture_output=True, text=True, timeout=60,
                         env=dict(env, LD_LIBRARY_PATH=str(libdir)))
    assert str(libdir / "libntscontact.so.0") in ldd.stdout


CORE_ONLY = r"""
#include <stdio.h>
#include <ntscontact/ntscontact.h>
int main(void) {
    static const nts_vec2 a[4] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}}, b[4] = {{0.95, 0.1}, {2, 0.1}, {2, 1.1}, {0.95, 1.1}};
    nts_body_def bodies[2] = {{0}, {0}};
    nts_scene_def def = nts_default_scene_def();
    nts_options o = nts_default_options();
    nts_context* c = nts_context_create();
    nts_error err;
    nts_result r;
    nts_scene* s;
    bodies[0].nodes = a; bodies[0].node_count = 4;
    bodies[1].nodes = b; bodies[1].node_count = 4;
    def.bodies = bodies; def.body_count = 2;
    s = nts_scene_create(&def, &err);
    o.penalty = 100.0; o.search_radius = 0.2; o.solver = NTS_SOLVER_CLOSED_FORM; o.threads = 2;
    if (s == NULL || nts_evaluate(c, s, &o, &r, &err) != NTS_OK) return 1;
    printf("contacts %d\n", r.summary.contacts);
    nts_scene_destroy(s);
    nts_context_destroy(c);
    return 0;
}
"""


@pytest.mark.skipif(shutil.which("cc") is None, reason="needs cc")
def test_readme_link_line_of_a_static_build(paths, tmp_path):
    """The README's link line by hand, for the static library, links and runs."""
    if sanitized(paths):
        pytest.skip("a sanitizer build: its static libraries need the sanitizer runtime in the consumer too")
    readme = " ".join((REPO / "README.md").read_text().split())
    m = re.search(r"`(cc app\.c -IPREFIX[^`]+)`", readme)
    assert m, "README: no `cc app.c ...` link line"
    prefix = tmp_path / "prefix"
    subprocess.run(["cmake", "--install", str(paths.build), "--prefix", str(prefix)], check=True,
                   capture_output=True, timeout=120)
    (tmp_path / "app.c").write_text(CORE_ONLY)
    config = (prefix / "include" / "ntscontact" / "config.h").read_text()
    args = m.group(1).replace("PREFIX", str(prefix)).split()
    if "NTS_CONFIG_OPENMP 0" in config:
        args = [a for a in args if a != "-fopenmp"]
    assert "-lgsl" in args and "-lgslcblas" in args and "-lm" in args
    r = subprocess.run([*args, "-o", "app"], cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, " ".join(args) + "\n" + r.stderr
    out = subprocess.run([str(tmp_path / "app")], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0 and int(out.stdout.split()[1]) > 0, out.stdout + out.stderr

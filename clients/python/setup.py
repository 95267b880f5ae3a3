"""Build hook of the ntscontact package: bundles the in-process engine.

``pip install ./clients/python`` runs the project's own CMake (the source tree
two levels up) for one target, ``ntscontact_engine`` (the core and the codec
in ``libntscontact_engine.so``, see ``codec/include/ntscontact/engine.h``), and
puts the library in the package as ``ntscontact/_lib/``. Where CMake, a C
compiler or the C libraries are missing (or the source tree is not there, as
in an sdist), the package installs without it: the HTTP client works, and
``ntscontact.Engine()`` says how to get the engine. ``NTSCONTACT_REQUIRE_ENGINE=1``
makes that a failure instead (the project's own install does that);
``NTSCONTACT_CMAKE`` names the cmake to run (default: ``cmake``).

setuptools rather than scikit-build-core: the engine is optional here, and a
failed CMake build must leave a working pure-Python install.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

from setuptools import Distribution, setup
from setuptools.command.build_py import build_py

HERE = Path(__file__).resolve().parent
SOURCE = HERE.parent.parent  # the project's top-level CMakeLists.txt
LIBRARY = "libntscontact_engine.so"


def _build_engine(build_temp: Path) -> Path:
    """Configure and build the engine target; the library's path."""
    if not (SOURCE / "CMakeLists.txt").is_file() or not (SOURCE / "codec" / "src" / "engine.c").is_file():
        raise RuntimeError(f"no ntscontact source tree at {SOURCE}")
    cmake = os.environ.get("NTSCONTACT_CMAKE", "cmake")
    if shutil.which(cmake) is None:
        raise RuntimeError(f"{cmake} not found")
    build = build_temp / "engine"
    subprocess.run([cmake, "-S", str(SOURCE), "-B", str(build), "-DCMAKE_BUILD_TYPE=Release", "-DNTS_BUILD_TESTS=OFF",
                    "-DNTS_COMPONENTS=codec", "-DNTS_FORTRAN=OFF"], check=True, stdout=subprocess.DEVNULL)
    subprocess.run([cmake, "--build", str(build), "--target", "ntscontact_engine", "-j", str(os.cpu_count() or 1)],
                   check=True, stdout=subprocess.DEVNULL)
    lib = build / "lib" / LIBRARY
    if not lib.is_file():
        raise RuntimeError(f"the build made no {lib}")
    return lib


class BuildWithEngine(build_py):
    """build_py, then the engine's library into the package's ``_lib/``."""

    def run(self) -> None:
        super().run()
        # An editable install imports from src/: the library goes there.
        target = (HERE / "src" if getattr(self, "editable_mode", False) else Path(self.build_lib)) / "ntscontact" / "_lib"
        try:
            lib = _build_engine(HERE / "build")  # kept between installs: a rebuild is incremental
        except (RuntimeError, OSError, subprocess.CalledProcessError) as exc:
            if os.environ.get("NTSCONTACT_REQUIRE_ENGINE") == "1":
                raise SystemExit(f"ntscontact: the in-process engine could not be built: {exc}")
            stale = target / LIBRARY  # from an earlier build in the same tree
            if stale.exists():
                stale.unlink()
            print(f"ntscontact: WARNING: installing without the in-process engine ({exc}); "
                  "ntscontact.Client works, ntscontact.Engine() will say how to get it", file=sys.stderr)
            return
        target.mkdir(parents=True, exist_ok=True)
        shutil.copy2(lib, target / LIBRARY)


class EngineDistribution(Distribution):
    """A wheel with a native library is not pure: tag it for this platform."""

    def has_ext_modules(self) -> bool:
        return True


commands: dict = {"build_py": BuildWithEngine}
try:
    from wheel.bdist_wheel import bdist_wheel

    class PlatformWheel(bdist_wheel):
        """py3-none-<platform>: the library is loaded through ctypes and does not
        depend on the Python version's ABI, only on the platform."""

        def get_tag(self) -> tuple:
            return ("py3", "none", super().get_tag()[2])

    commands["bdist_wheel"] = PlatformWheel
except ImportError:  # no wheel package: setuptools builds no wheel either
    pass

setup(cmdclass=commands, distclass=EngineDistribution)

#!/usr/bin/env bash
# Install what ntscontact needs on Debian 12: the C toolchain and libraries from
# Debian's packages (through sudo when not root), and a Python virtual
# environment in .venv for the tests and the client. Idempotent and quiet when
# everything is already there.
set -euo pipefail
cd "$(dirname "$0")/.."

# valgrind, clang and its sanitizer/fuzzer runtime serve the reliability checks
# of scripts/test.sh (memcheck of the CLI and daemon, the bounded libFuzzer run);
# nginx serves the scale-out test (deploy/), openssl makes the HTTPS test's certificate;
# gfortran builds the Fortran module (fortran/) and its test, skipped without it; doxygen
# builds the C API reference (scripts/docs.sh, tests/python/test_api_docs.py); Open MPI
# builds and runs the distributed evaluation (mpi/, docs/distributed.md) and its tests; locales
# gives localedef the sources of a decimal-comma locale (tests/python/test_numbers_locale.py);
# wrk drives the load benchmarks (bench/load/run.sh, bench/scale_out.py).
pkgs=(build-essential cmake pkg-config libgsl-dev libcjson-dev libmicrohttpd-dev libcunit1-dev doxygen
      curl python3 python3-venv valgrind clang libclang-rt-14-dev nginx openssl gfortran
      libopenmpi-dev openmpi-bin locales wrk)
[ -n "${NTS_EXTRA_PKGS:-}" ] && read -r -a extra <<<"$NTS_EXTRA_PKGS" && pkgs+=("${extra[@]}")
missing=()
for p in "${pkgs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  SUDO=""
  if [ "$(id -u)" -ne 0 ]; then
    if ! command -v sudo >/dev/null 2>&1; then
      echo "install-deps: these Debian packages are missing: ${missing[*]}" >&2
      echo "install-deps: you are not root and sudo is not installed; as root, run:" >&2
      echo "  apt-get install ${missing[*]}" >&2
      exit 1
    fi
    SUDO="sudo"
  fi
  echo "install-deps: apt-get install ${missing[*]}" >&2
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${missing[@]}" >/dev/null
fi

if [ ! -x .venv/bin/python ]; then
  python3 -m venv .venv
fi
req=requirements-dev.txt
stamp=.venv/.req-stamp
if [ ! -f "$stamp" ] || ! cmp -s "$req" "$stamp"; then
  # NTSCONTACT_REQUIRE_ENGINE: the package must bundle the in-process engine
  # (clients/python/setup.py builds it with this CMake; without it, a failure).
  NTSCONTACT_REQUIRE_ENGINE=1 .venv/bin/pip install -q --disable-pip-version-check -r "$req"
  cp "$req" "$stamp"
fi

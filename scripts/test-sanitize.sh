#!/usr/bin/env bash
# The whole test suite again under AddressSanitizer + UndefinedBehaviorSanitizer
# (-DNTS_SANITIZE=ON, no recover), the asserts on: every CUnit suite through ctest (the fuzz
# corpus replay and the allocation-failure sweeps among them) and every pytest
# suite, the tests finding the sanitized binaries through NTS_BUILD_DIR.
# Builds into build-asan/ (or $NTS_ASAN_BUILD_DIR). Any sanitizer report aborts
# the process at fault, so its test fails; LeakSanitizer runs at every exit.
set -euo pipefail
cd "$(dirname "$0")/.."
dir=${NTS_ASAN_BUILD_DIR:-build-asan}
[ -x .venv/bin/python ] || bash scripts/install-deps.sh
# With the asserts on: RelWithDebInfo defines NDEBUG, and every other build
# here is one, so without this no test would ever run the asserts inside.
NTS_BUILD_DIR="$dir" bash scripts/build.sh -DNTS_SANITIZE=ON -DNTS_WERROR=ON "-DCMAKE_C_FLAGS_RELWITHDEBINFO=-O2 -g" "$@"

export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=1:halt_on_error=1:detect_stack_use_after_return=1:strict_string_checks=1:check_initialization_order=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}

(cd "$dir" && ctest --output-on-failure)
if [ -d tests/python ]; then
  set +e
  NTS_BUILD_DIR="$PWD/$dir" NTS_SANITIZED=1 .venv/bin/python -m pytest -q tests/python
  rc=$?
  set -e
  [ $rc -eq 5 ] && rc=0   # no tests collected is not a failure of the suite
  [ $rc -ne 0 ] && exit $rc
fi
echo "sanitized tests passed"

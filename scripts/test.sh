#!/usr/bin/env bash
# Build everything and run every test: CUnit (through ctest) and pytest.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
NTS_BUILD_DIR=build bash scripts/build.sh -DNTS_WERROR=ON
(cd build && ctest --output-on-failure)
if [ -d tests/python ]; then
  set +e
  NTS_BUILD_DIR="$PWD/build" .venv/bin/python -m pytest -q tests/python
  rc=$?
  set -e
  [ $rc -eq 5 ] && rc=0   # no tests collected is not a failure of the suite
  [ $rc -ne 0 ] && exit $rc
fi
echo "all tests passed"

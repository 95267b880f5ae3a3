#!/usr/bin/env bash
# Configure and build into build/ (or $NTS_BUILD_DIR); extra arguments go to cmake.
set -euo pipefail
cd "$(dirname "$0")/.."
dir=${NTS_BUILD_DIR:-build}
cmake -S . -B "$dir" -DCMAKE_BUILD_TYPE=RelWithDebInfo "$@" >/dev/null
cmake --build "$dir" -j "$(nproc)" >/dev/null
# The Python package's in-process engine: an editable install (install-deps.sh
# makes one) builds its own copy of the library once, into
# clients/python/src/ntscontact/_lib/, which Engine() loads; brought up to date
# with the sources here, as a reinstall would (incremental: nothing to do when
# they did not change).
engine=clients/python/build/engine
lib=clients/python/src/ntscontact/_lib
if [ -f "$engine/CMakeCache.txt" ] && [ -d "$lib" ]; then
  cmake --build "$engine" --target ntscontact_engine -j "$(nproc)" >/dev/null
  cmp -s "$engine/lib/libntscontact_engine.so" "$lib/libntscontact_engine.so" ||
    cp -p "$engine/lib/libntscontact_engine.so" "$lib/libntscontact_engine.so"
fi

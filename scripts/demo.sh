#!/usr/bin/env bash
# Build and run the main job on a bundled example.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
NTS_BUILD_DIR=build bash scripts/build.sh
./build/bin/two_disks

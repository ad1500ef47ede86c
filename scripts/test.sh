#!/usr/bin/env bash
# Quick start, step 2: install dependencies, build (warnings are errors), run the whole test suite.
# Tests that need ../shared (real data and models beside the checkout) skip with a message when it
# is absent; point SUPERDYNA_SHARED_DIR elsewhere to use another copy.
set -euo pipefail
repo_dir=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
SUPERDYNA_WERROR=${SUPERDYNA_WERROR:-ON} "$repo_dir/scripts/setup.sh"
build_dir=${BUILD_DIR:-"$repo_dir/build"}
ctest --test-dir "$build_dir" --output-on-failure -j "${JOBS:-$(nproc)}" --timeout 1200

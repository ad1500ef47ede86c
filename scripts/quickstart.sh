#!/usr/bin/env bash
# Quick start, step 1: install dependencies, build, and run the main job on the built-in default.
# Today the main job is the evaluation demo: a generated flight, a drifting estimate of it, and
# ATE / RPE after SE(3) and Sim(3) alignment (table, JSON and plot in superdyna_demo/).
set -euo pipefail
repo_dir=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
"$repo_dir/scripts/setup.sh"
build_dir=${BUILD_DIR:-"$repo_dir/build"}
"$build_dir/bin/superdyna" demo --out "${DEMO_DIR:-$repo_dir/superdyna_demo}" "$@"

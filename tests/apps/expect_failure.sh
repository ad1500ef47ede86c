#!/usr/bin/env bash
# Passes when COMMAND fails (exits non-zero) and its output contains FRAGMENT: for tests of
# switches that must turn a run into a failure.
# Usage: expect_failure.sh FRAGMENT COMMAND [ARGUMENT...]
set -uo pipefail
fragment=$1
shift
output=$("$@" 2>&1)
code=$?
echo "$output"
[ "$code" -ne 0 ] || { echo "expected a failure, the command exited with 0"; exit 1; }
grep -qF -- "$fragment" <<<"$output" || { echo "output lacks '$fragment'"; exit 1; }
echo "failed as expected (exit code $code)"

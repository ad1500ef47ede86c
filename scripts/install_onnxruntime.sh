#!/usr/bin/env bash
# Makes ONNX Runtime (C/C++ API, CPU) available to the build. Debian bookworm does not package it.
#
#  1. An existing install is used as it is, found through
#       - $ONNXRUNTIME_ROOT (include/[onnxruntime/]onnxruntime_cxx_api.h and lib*/libonnxruntime.so*),
#       - an ONNX Runtime CMake package (onnxruntimeConfig.cmake / onnxruntime-config.cmake) under
#         $CMAKE_PREFIX_PATH, /usr/local, /usr or /opt/onnxruntime*,
#       - pkg-config (libonnxruntime.pc).
#  2. Otherwise the npm registry package com.github.asus4.onnxruntime@0.4.9 (MIT; it ships the
#     official ONNX Runtime 1.29 headers and Linux x64 library) is fetched with `npm pack`, its
#     tarball checked against the pinned sha512 below, and the headers, the library and the licence
#     copied into $SUPERDYNA_ORT_PREFIX (default <repo>/.deps/onnxruntime: include/, lib/).
#     CMake (cmake/FindOnnxRuntime.cmake) looks there after $ONNXRUNTIME_ROOT.
#
# Idempotent: a prefix whose stamp file names this package, version and checksum, and whose header
# and library are present, is kept. Needs `npm` for step 2 (installs Debian's nodejs and npm when
# the command is absent; as root or through sudo).
#
# Environment: ONNXRUNTIME_ROOT, SUPERDYNA_ORT_PREFIX, SUPERDYNA_ORT_LOCAL=1 (skip step 1 and always
# use the local prefix).
set -euo pipefail

repo_dir=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
prefix=${SUPERDYNA_ORT_PREFIX:-"$repo_dir/.deps/onnxruntime"}

readonly npm_package="com.github.asus4.onnxruntime"
readonly npm_version="0.4.9"
readonly ort_version="1.29.0"
readonly npm_integrity="sha512-BkzxduSZ9IkeDP6Q8lz2TFU2ie7hSSvS7ZIfzMooExoq0CNzJnuuGaUJ7IsojBgqO4ouD1jXah8OYyJbCN29Fg=="
# Paths inside the tarball. The headers are identical in every framework of the xcframework.
readonly tar_headers="package/Plugins/iOS~/onnxruntime.xcframework/ios-arm64/onnxruntime.framework/Headers"
readonly tar_libdir="package/Plugins/Linux/x64"
readonly stamp_text="$npm_package@$npm_version $npm_integrity onnxruntime $ort_version"
# shellcheck source=scripts/npm_package.sh
source "$repo_dir/scripts/npm_package.sh"

log() { echo "[onnxruntime] $*"; }
fail() {
  echo "[onnxruntime] error: $*" >&2
  exit 1
}

# A folder holding the ONNX Runtime C++ header and shared library.
is_ort_root() {
  local root=$1
  { [ -f "$root/include/onnxruntime_cxx_api.h" ] ||
    [ -f "$root/include/onnxruntime/onnxruntime_cxx_api.h" ] ||
    [ -f "$root/include/onnxruntime/core/session/onnxruntime_cxx_api.h" ]; } || return 1
  compgen -G "$root/lib*/libonnxruntime.so*" >/dev/null ||
    compgen -G "$root/lib/*-linux-gnu/libonnxruntime.so*" >/dev/null
}

find_cmake_package() {
  local dirs=() dir candidate
  IFS=: read -r -a dirs <<<"${CMAKE_PREFIX_PATH:-}"
  dirs+=(/usr/local /usr)
  for dir in /opt/onnxruntime*; do [ -d "$dir" ] && dirs+=("$dir"); done
  for dir in "${dirs[@]}"; do
    [ -n "$dir" ] || continue
    for candidate in "$dir"/lib*/cmake/onnxruntime/onnxruntime{Config,-config}.cmake \
      "$dir"/lib/*-linux-gnu/cmake/onnxruntime/onnxruntime{Config,-config}.cmake; do
      if [ -f "$candidate" ]; then
        echo "$candidate"
        return 0
      fi
    done
  done
  return 1
}

find_system_install() {
  local config
  if config=$(find_cmake_package); then
    echo "CMake package $config"
    return 0
  fi
  if command -v pkg-config >/dev/null 2>&1 && pkg-config --exists libonnxruntime 2>/dev/null; then
    echo "pkg-config libonnxruntime $(pkg-config --modversion libonnxruntime)"
    return 0
  fi
  return 1
}

prefix_is_current() {
  [ -f "$prefix/INSTALLED" ] && [ "$(cat "$prefix/INSTALLED")" = "$stamp_text" ] &&
    [ -f "$prefix/include/onnxruntime_cxx_api.h" ] && [ -f "$prefix/lib/libonnxruntime.so.$ort_version" ]
}

install_local() {
  [ "$(uname -s)" = Linux ] && [ "$(uname -m)" = x86_64 ] ||
    fail "the npm package only carries a Linux x86_64 library; on $(uname -s) $(uname -m) install ONNX Runtime (distribution package or official release archive) and set ONNXRUNTIME_ROOT"
  local tmp
  tmp=$(mktemp -d)
  # shellcheck disable=SC2064  # expand $tmp now
  trap "rm -rf '$tmp'" EXIT
  log "fetching $npm_package@$npm_version from the npm registry (150 MB)"
  local tarball
  tarball=$(npm_fetch "$npm_package" "$npm_version" "$npm_integrity" "$tmp")
  log "checksum verified ($npm_integrity)"

  tar -xzf "$tarball" -C "$tmp" "$tar_headers" "$tar_libdir/libonnxruntime.so" \
    "$tar_libdir/libonnxruntime_providers_shared.so" package/LICENSE
  local stage="$prefix.partial.$$"
  rm -rf "$stage"
  mkdir -p "$stage/include" "$stage/lib"
  cp "$tmp/$tar_headers"/*.h "$stage/include/"
  # The library's SONAME is libonnxruntime.so.1: install the usual three names.
  cp "$tmp/$tar_libdir/libonnxruntime.so" "$stage/lib/libonnxruntime.so.$ort_version"
  ln -s "libonnxruntime.so.$ort_version" "$stage/lib/libonnxruntime.so.1"
  ln -s "libonnxruntime.so.1" "$stage/lib/libonnxruntime.so"
  cp "$tmp/$tar_libdir/libonnxruntime_providers_shared.so" "$stage/lib/"
  cp "$tmp/package/LICENSE" "$stage/LICENSE"
  echo "$stamp_text" >"$stage/INSTALLED"
  rm -rf "$prefix"
  mkdir -p "$(dirname "$prefix")"
  mv "$stage" "$prefix"
  log "installed ONNX Runtime $ort_version into $prefix"
}

main() {
  local found
  if [ -n "${ONNXRUNTIME_ROOT:-}" ]; then
    is_ort_root "$ONNXRUNTIME_ROOT" ||
      fail "ONNXRUNTIME_ROOT=$ONNXRUNTIME_ROOT lacks include/onnxruntime_cxx_api.h or lib/libonnxruntime.so"
    log "using ONNXRUNTIME_ROOT=$ONNXRUNTIME_ROOT"
    return 0
  fi
  if [ "${SUPERDYNA_ORT_LOCAL:-0}" != 1 ] && found=$(find_system_install); then
    log "using the installed ONNX Runtime ($found)"
    return 0
  fi
  if prefix_is_current; then
    log "ONNX Runtime $ort_version present in $prefix"
    return 0
  fi
  install_local
}

main "$@"

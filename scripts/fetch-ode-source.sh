#!/usr/bin/env bash
# Fetches ODE's source (the version Debian ships as libode-dev) for the
# compatibility suite in tests/ode_compat: ODE's own unit tests and demo
# programs, built against the system libode and run plain and under
# blockstep. Nothing of it is kept in the repository.
#   scripts/fetch-ode-source.sh DIR    unpacks into DIR/ode-<version>
# Prints the unpacked directory. Safe to run twice (a complete copy is
# reused). Needs Debian's source index (scripts/install-deps.sh enables it).
set -euo pipefail

dest="${1:?usage: fetch-ode-source.sh DIR}"
mkdir -p "$dest"
dest="$(cd "$dest" && pwd)"

version="$(dpkg-query -W -f='${Version}' libode-dev 2>/dev/null || true)"
if [ -z "$version" ]; then
  echo "fetch-ode-source: libode-dev is not installed (scripts/install-deps.sh)" >&2
  exit 1
fi
plain_version="${version#*:}"     # file names carry no epoch
upstream="${plain_version%-*}"
tree="$dest/ode-$upstream"
done_mark="$tree/.blockstep-configured"

if [ ! -f "$done_mark" ]; then
  rm -rf "$tree"
  (cd "$dest" && apt-get source --download-only "ode=$version" >/dev/null 2>"$dest/apt-source.log" ||
     { echo "fetch-ode-source: apt-get source ode=$version failed:" >&2; cat "$dest/apt-source.log" >&2; exit 1; })
  (cd "$dest" && dpkg-source --no-check -x "ode_${plain_version}.dsc" "ode-$upstream" >/dev/null)
  # ODE's internal headers, which its unit tests include, need the
  # config.h of a build configured as Debian's (debian/rules).
  (cd "$tree" && ./configure --enable-double-precision --with-libccd=system --enable-libccd \
      --enable-shared --enable-static >"$dest/configure.log" 2>&1 ||
     { echo "fetch-ode-source: ODE's configure failed (see $dest/configure.log)" >&2; exit 1; })
  touch "$done_mark"
fi
echo "$tree"

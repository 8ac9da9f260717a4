#!/usr/bin/env bash
# Installs blockstep's build and test dependencies from Debian's packages
# (three.js for the comparison report's replay, Chromium to test that
# report headless).
# Safe to run twice: packages already present are not fetched again, and
# `apt-get update` only runs when something is missing.
set -euo pipefail

packages=(
  build-essential cmake pkg-config clang-format dpkg-dev
  libeigen3-dev libccd-dev libode-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  libcli11-dev nlohmann-json3-dev python3-matplotlib libtbb-dev
  libjs-three chromium
)

# ODE's own unit tests and demos (tests/ode_compat) are built from ODE's
# source, fetched with `apt-get source ode`: that needs Debian's source
# index. The entry mirrors the machine's own binary one.
source_list=/etc/apt/sources.list.d/blockstep-deb-src.sources
need_update=0
if ! grep -rqs "^Types:.*deb-src\|^deb-src" /etc/apt/sources.list /etc/apt/sources.list.d/; then
  if [ "$(id -u)" -ne 0 ]; then
    echo "install-deps: Debian's source index (deb-src) is not enabled; run as root" >&2
    exit 1
  fi
  binary_list=/etc/apt/sources.list.d/debian.sources
  if [ -f "$binary_list" ]; then
    sed 's/^Types: deb$/Types: deb-src/' "$binary_list" > "$source_list"
  else
    cat > "$source_list" <<'SOURCES'
Types: deb-src
URIs: http://deb.debian.org/debian
Suites: bookworm bookworm-updates
Components: main
Signed-By: /usr/share/keyrings/debian-archive-keyring.gpg
SOURCES
  fi
  echo "install-deps: enabled Debian's source index in $source_list"
  need_update=1
fi

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  if [ "$need_update" -eq 1 ]; then
    apt-get update -qq
  fi
  echo "install-deps: all ${#packages[@]} packages present"
  exit 0
fi

if [ "$(id -u)" -ne 0 ]; then
  echo "install-deps: missing packages: ${missing[*]}" >&2
  echo "install-deps: run as root (or install them with apt-get) and try again" >&2
  exit 1
fi

echo "install-deps: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
apt-get update -qq
apt-get install -y -qq --no-install-recommends "${missing[@]}"

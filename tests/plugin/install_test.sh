#!/bin/sh
# Installs the build into a scratch prefix, then builds and runs an ODE
# program against it twice: with find_package(blockstep) and with
# pkg-config, as an ODE program would add blockstep.
# Usage: install_test.sh <build dir> <consumer source dir> <scratch dir>
set -eu
build=$1 source=$2 scratch=$3
rm -rf "$scratch"
cmake --install "$build" --prefix "$scratch/prefix" >/dev/null
cmake -S "$source" -B "$scratch/cmake-build" -DCMAKE_PREFIX_PATH="$scratch/prefix" >/dev/null
cmake --build "$scratch/cmake-build" >/dev/null
LD_LIBRARY_PATH="$scratch/prefix/lib" BLOCKSTEP_QUIET=1 "$scratch/cmake-build/consumer"
libdir=$(ls -d "$scratch"/prefix/lib*/pkgconfig)
PKG_CONFIG_PATH="$libdir" cc "$source/consumer.c" -o "$scratch/consumer-pc" \
  $(PKG_CONFIG_PATH="$libdir" pkg-config --cflags --libs blockstep_ode) -lm
LD_LIBRARY_PATH="$(dirname "$libdir")" BLOCKSTEP_QUIET=1 "$scratch/consumer-pc"

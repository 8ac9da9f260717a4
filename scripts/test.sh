#!/usr/bin/env bash
# Builds blockstep and runs every test suite. Installs missing Debian
# packages first (as root). Safe to run twice.
#   scripts/test.sh            Release build in build/
#   BLOCKSTEP_SANITIZE=ON scripts/test.sh   ASan + UBSan build in build-sanitize/
# The threaded tests also run under ThreadSanitizer (build-tsan/).
set -euo pipefail
cd "$(dirname "$0")/.."

bash scripts/install-deps.sh

sanitize="${BLOCKSTEP_SANITIZE:-OFF}"
build_dir=build
timeout=300
if [ "$sanitize" = "ON" ]; then
  build_dir=build-sanitize
  timeout=1800  # the 2000-frame pyramid runs about ten times slower instrumented
fi

# ODE's own unit tests and demos run in the suite: their source is fetched
# here (tests/ode_compat), never kept in the repository.
mkdir -p "$build_dir"
ode_source="$(bash scripts/fetch-ode-source.sh "$build_dir/ode-source")"

cmake -S . -B "$build_dir" -DCMAKE_BUILD_TYPE=Release -DBLOCKSTEP_SANITIZE="$sanitize" \
  -DBLOCKSTEP_ODE_SOURCE_DIR="$ode_source"
cmake --build "$build_dir" --parallel "$(nproc)"
ctest --test-dir "$build_dir" --output-on-failure --parallel "$(nproc)" --timeout "$timeout"

# The threaded tests once more, under ThreadSanitizer: a data race between
# worlds stepped on different threads fails them.
if [ "$sanitize" != "ON" ]; then
  cmake -S . -B build-tsan -DCMAKE_BUILD_TYPE=RelWithDebInfo -DBLOCKSTEP_TSAN=ON \
    -DBLOCKSTEP_BUILD_BENCHMARKS=OFF > /dev/null
  cmake --build build-tsan --parallel "$(nproc)" --target plugin_tests adapter_tests
  export TSAN_OPTIONS="halt_on_error=1 exitcode=66"
  # Not the islands swept on TBB's threads: Debian's libtbb is not built
  # with ThreadSanitizer, so its hand-offs to its workers are invisible and
  # every datum a worker reads looks raced (their test compares every
  # thread count's bits with one thread's instead).
  build-tsan/tests/plugin_tests --gtest_filter='PluginThreads.*:-PluginThreads.IslandsSwept*'
  build-tsan/tests/adapter_tests --gtest_filter='RegistryThreads.*'
fi

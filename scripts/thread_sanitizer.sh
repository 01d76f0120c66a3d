#!/usr/bin/env bash
# Builds the C++ tests with ThreadSanitizer (-fsanitize=thread) and runs the thread-contract
# tests (tests/cpp/test_threads.cpp): several threads, each stepping its own controller or
# mechanism set over shared devices, mechanisms and shapes, must race on nothing. Needs the
# .venv of scripts/setup.sh (Eigen from cmeel-eigen, as scripts/test.sh installs it), g++ or
# clang++ with libtsan, and GoogleTest. Usage: bash scripts/thread_sanitizer.sh [build dir]
set -euo pipefail
cd "$(dirname "$0")/.."
out="${1:-build/tsan}"
.venv/bin/python -m pip install -q "cmeel-eigen>=3.4"
generator=()
command -v ninja >/dev/null 2>&1 && generator=(-G Ninja)
cmake -S . -B "$out" "${generator[@]}" -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DVIRTMECH_BUILD_TESTS=ON -DVIRTMECH_BUILD_EXAMPLES=OFF \
  -DCMAKE_CXX_FLAGS="-fsanitize=thread -fno-omit-frame-pointer" \
  -DCMAKE_EXE_LINKER_FLAGS="-fsanitize=thread" \
  -DPython_EXECUTABLE="$PWD/.venv/bin/python" >/dev/null
cmake --build "$out" -j 2 --target virtmech_tests
TSAN_OPTIONS="halt_on_error=1 second_deadlock_stack=1" \
  "$out/tests/cpp/virtmech_tests" --gtest_filter='Threads.*'

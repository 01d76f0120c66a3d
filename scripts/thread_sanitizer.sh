#!/usr/bin/env bash
# Builds the thread-contract tests (tests/cpp/test_threads.cpp) and the core with
# ThreadSanitizer (-fsanitize=thread) and runs them: several threads, each stepping its own
# controller or mechanism set over shared devices, mechanisms and shapes, must race on
# nothing. Needs g++ (or clang++) with libtsan and GoogleTest; Eigen from the .venv as
# scripts/test.sh installs it. Usage: bash scripts/thread_sanitizer.sh [build dir]
set -euo pipefail
cd "$(dirname "$0")/.."
out="${1:-build/tsan}"
mkdir -p "$out"
cxx="${CXX:-g++}"
eigen="$(find .venv -path '*cmeel.prefix/include/eigen3' -maxdepth 6 | head -n 1)"
if [ -z "$eigen" ]; then
  echo "thread_sanitizer: Eigen not found under .venv (pip install cmeel-eigen)" >&2
  exit 1
fi
flags=(-std=c++17 -O1 -g -fsanitize=thread -fno-omit-frame-pointer -Iinclude -Isrc -Itests/cpp
       -isystem "$eigen")
objs=()
for src in src/*.cpp tests/cpp/test_threads.cpp; do
  obj="$out/$(basename "${src%.cpp}").o"
  if [ ! -f "$obj" ] || [ "$src" -nt "$obj" ]; then
    "$cxx" "${flags[@]}" -c "$src" -o "$obj"
  fi
  objs+=("$obj")
done
"$cxx" -fsanitize=thread "${objs[@]}" -lgtest -lgtest_main -pthread -o "$out/thread_tests"
TSAN_OPTIONS="halt_on_error=1 second_deadlock_stack=1" "$out/thread_tests"

#!/usr/bin/env bash
# Sets up everything and runs every test: the C++ core with GoogleTest (CTest), the
# installed CMake package through a downstream find_package(virtmech) project, the C and
# C++ examples, and the Python suite (pytest).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh test
.venv/bin/python -m pip install -q "cmeel-eigen>=3.4"  # Eigen for the stand-alone CMake build

generator=()
command -v ninja >/dev/null 2>&1 && generator=(-G Ninja)
jobs="$(nproc 2>/dev/null || echo 2)"

echo "== C++: build and GoogleTest"
cmake -S . -B build/cpp "${generator[@]}" -DCMAKE_BUILD_TYPE=Release \
  -DVIRTMECH_BUILD_TESTS=ON -DVIRTMECH_BUILD_EXAMPLES=ON \
  -DPython_EXECUTABLE="$PWD/.venv/bin/python" -DCMAKE_INSTALL_PREFIX="$PWD/build/prefix" >/dev/null
cmake --build build/cpp -j "$jobs"
# ctest's line per test (some 250, dotted out to a column) to a log: here its summary, or
# all of it when a test fails
ctest_log=build/cpp/ctest.log
echo "ctest: $(ctest --test-dir build/cpp -N | tail -n 1) (each test's line: $ctest_log)"
if ctest --test-dir build/cpp --output-on-failure -j "$jobs" >"$ctest_log" 2>&1; then
  grep -E "tests passed|Total Test time" "$ctest_log"
else
  cat "$ctest_log"
  exit 1
fi

# the same suites over the core built on <cmath> (its own atan2, rotation logarithm's series
# and cycle clock replaced by the library's: docs/performance.md); the allocation-free build
# above does not depend on it
echo "== C++: the core on <cmath> (VIRTMECH_STD_MATH=ON): build and GoogleTest"
cmake -S . -B build/cpp-std-math "${generator[@]}" -DCMAKE_BUILD_TYPE=Release \
  -DVIRTMECH_BUILD_TESTS=ON -DVIRTMECH_STD_MATH=ON \
  -DPython_EXECUTABLE="$PWD/.venv/bin/python" >/dev/null
std_math_tests=(virtmech_tests)
[ -f build/cpp/tests/cpp/virtmech_sim_tests ] && std_math_tests+=(virtmech_sim_tests)
cmake --build build/cpp-std-math -j "$jobs" --target "${std_math_tests[@]}"
for t in "${std_math_tests[@]}"; do
  build/cpp-std-math/tests/cpp/"$t" --gtest_brief=1
done

echo "== C++: install, then find_package(virtmech) from a downstream project"
cmake --install build/cpp >/dev/null
eigen_prefix="$(.venv/bin/python -c 'import os, sysconfig; print(os.path.join(sysconfig.get_paths()["purelib"], "cmeel.prefix"))')"
cmake -S tests/cmake_consumer -B build/consumer "${generator[@]}" \
  -DCMAKE_PREFIX_PATH="$PWD/build/prefix;$eigen_prefix" >/dev/null
cmake --build build/consumer -j "$jobs" >/dev/null
build/consumer/consumer

echo "== examples"
example() {  # an example's title and column headings, then its last rows
  local out
  out="$("$@")"
  head -n 2 <<<"$out"
  echo "     ..."
  tail -n 3 <<<"$out"
}
example build/cpp/examples/01_omni_loop_c build/cpp/tests/standin/libHD.so  # an HD program, on the stand-in
example build/cpp/examples/01_omni_loop_cpp
example build/cpp/examples/02_custom_mechanism_cpp
example build/cpp/examples/surface_probe_c
example .venv/bin/python examples/python/01_omni_loop.py

echo "== Python: ruff"
.venv/bin/ruff check python tests/python tests/reference examples/python

# readable sizes: any function longer than 80 lines or of cyclomatic complexity above 20 in
# the core, the simulation or the Python package (its bindings included) fails the suite
echo "== lizard: no function over 80 lines or cyclomatic complexity 20"
.venv/bin/lizard -L 80 -C 20 -w src include sim python

# the suite (tests marked slow excluded: pyproject.toml's addopts), then the slow ones: the
# thorough variants of the global-optimum and reference checks and the bench's NumPy column
for marks in "" "slow"; do
  echo "== Python: pytest${marks:+ -m $marks}"
  set +e
  .venv/bin/python -m pytest ${marks:+-m "$marks"}
  rc=$?
  set -e
  if [ "$rc" -eq 5 ]; then
    echo "pytest collected no tests${marks:+ marked $marks}: the suite is misconfigured" >&2
    exit 1
  fi
  [ "$rc" -eq 0 ] || exit "$rc"
done

#!/usr/bin/env bash
# Builds and runs the cycle benchmarks (docs/performance.md): the per-cycle latency harness
# (median, p99, p99.9, worst over 1e6 cycles per case, allocations counted), the Google
# Benchmark suite of the cycle and its parts, then `virtmech bench` from the virtual
# environment with the NumPy reference cycle of tests/reference (bench/numpy_baseline.py:
# C++ against Python and NumPy; and the simulation's real-time factor).
#
#   scripts/bench.sh                    this tree
#   scripts/bench.sh --compare REV      also REV's core under the same harness, run back to back
#   scripts/bench.sh --cycles N --cpu K timed cycles per case; pin the harness to CPU K
set -euo pipefail
cd "$(dirname "$0")/.."
compare=""
cycles=1000000
cpu=()
while [ $# -gt 0 ]; do
  case "$1" in
    --compare) compare="$2"; shift 2 ;;
    --cycles) cycles="$2"; shift 2 ;;
    --cpu) cpu=(--cpu "$2"); shift 2 ;;
    *) echo "usage: scripts/bench.sh [--compare REV] [--cycles N] [--cpu K]" >&2; exit 2 ;;
  esac
done
if [ -z "${PYTHON:-}" ]; then
  # the virtual environment with the simulation, and Google Benchmark (Debian)
  VIRTMECH_SETUP_BENCHMARK=1 bash scripts/setup.sh sim
fi
py="${PYTHON:-$PWD/.venv/bin/python}"
generator=()
command -v ninja >/dev/null 2>&1 && generator=(-G Ninja)
jobs="$(nproc 2>/dev/null || echo 2)"

build() {  # source dir, build dir[, target]
  cmake -S "$1" -B "$2" "${generator[@]}" -DCMAKE_BUILD_TYPE=Release -DVIRTMECH_BUILD_BENCH=ON \
    -DPython_EXECUTABLE="$py" >/dev/null
  cmake --build "$2" -j "$jobs" ${3:+--target "$3"} >/dev/null
}

echo "== build (Release)"
build . build/bench
base=""
if [ -n "$compare" ]; then
  base="$(mktemp -d)"
  trap 'git worktree remove --force "$base/src" >/dev/null 2>&1 || true; rm -rf "$base"' EXIT
  git worktree add --detach "$base/src" "$compare" >/dev/null
  rm -rf "$base/src/bench"
  cp -r bench "$base/src/bench"  # this tree's harness over REV's core
  # the latency harness only: the Google Benchmark suite also times parts REV may not have
  build "$base/src" "$base/build" virtmech_cycle_bench
fi

echo "== per-cycle latency: $(git rev-parse --short HEAD)$(git diff --quiet HEAD -- src include || echo '+changes')"
build/bench/bench/virtmech_cycle_bench --cycles "$cycles" "${cpu[@]}"
if [ -n "$compare" ]; then
  echo
  echo "== per-cycle latency: $compare ($(git rev-parse --short "$compare")), same harness"
  "$base/build/bench/virtmech_cycle_bench" --cycles "$cycles" "${cpu[@]}"
fi

gbench=(--benchmark_repetitions=3 --benchmark_report_aggregates_only=true)
if [ -x build/bench/bench/virtmech_bm ]; then
  echo
  echo "== Google Benchmark: the cycle and its parts"
  build/bench/bench/virtmech_bm "${gbench[@]}"
  if [ -n "$compare" ] && [ -x "$base/build/bench/virtmech_bm" ]; then
    echo
    echo "== Google Benchmark: $compare"
    "$base/build/bench/virtmech_bm" "${gbench[@]}"
  fi
fi

echo
if "$py" -c "import virtmech.bench" >/dev/null 2>&1; then
  echo "== virtmech bench (installed package) with the NumPy reference of this checkout"
  "$py" bench/numpy_baseline.py --cycles "$cycles" "${cpu[@]}"
else
  echo "== virtmech bench: virtmech is not installed for $py (scripts/setup.sh)"
fi

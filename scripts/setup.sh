#!/usr/bin/env bash
# Sets up a fresh machine for virtmech: system build tools (Debian packages, when missing and
# we are root), a virtual environment in .venv, and virtmech installed into it with the
# extras named in $1 (e.g. "sim" or "test"). Idempotent: a second run reuses everything.
set -euo pipefail
cd "$(dirname "$0")/.."
extras="${1:-}"

need=()
command -v cmake >/dev/null 2>&1 || need+=(cmake)
command -v ninja >/dev/null 2>&1 || need+=(ninja-build)
command -v g++ >/dev/null 2>&1 || need+=(g++)
if [ "$extras" = "test" ]; then
  [ -f /usr/include/gtest/gtest.h ] || need+=(libgtest-dev)
fi
if [ "${VIRTMECH_SETUP_BENCHMARK:-0}" = "1" ]; then
  [ -f /usr/include/benchmark/benchmark.h ] || need+=(libbenchmark-dev)
fi
if [ "${#need[@]}" -gt 0 ]; then
  if [ "$(id -u)" = "0" ]; then
    echo "setup: installing ${need[*]} (Debian packages)"
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${need[@]}" >/dev/null
  else
    echo "setup: missing ${need[*]}; install them (Debian: apt-get install ${need[*]})" >&2
    exit 1
  fi
fi

py="${PYTHON:-python3}"
if [ ! -x .venv/bin/python ]; then
  echo "setup: creating .venv with $($py --version)"
  "$py" -m venv .venv
fi
.venv/bin/python -m pip install -q --upgrade "pip>=23.1"
spec="."
[ -n "$extras" ] && spec=".[$extras]"
echo "setup: pip install $spec (builds the C++ core and its Python extension)"
.venv/bin/python -m pip install -q "$spec"

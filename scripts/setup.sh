#!/usr/bin/env bash
# Sets up a fresh machine for virtmech: system build tools (Debian packages, when missing and
# we are root), a virtual environment in .venv, and virtmech installed into it with the
# extras named in $1 (e.g. "sim" or "test"). Idempotent: with nothing changed a second run
# neither rebuilds nor reinstalls (about a second).
set -euo pipefail
cd "$(dirname "$0")/.."
extras="${1:-}"

need=()
command -v cmake >/dev/null 2>&1 || need+=(cmake)
command -v ninja >/dev/null 2>&1 || need+=(ninja-build)
command -v g++ >/dev/null 2>&1 || need+=(g++)
if [ "$extras" = "test" ]; then
  [ -f /usr/include/gtest/gtest.h ] || need+=(libgtest-dev)
  # the viewer's browser test (tests/python/test_view.py) drives Debian's Chromium
  [ -x /usr/bin/chromium ] || need+=(chromium)
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
  .venv/bin/python -m pip install -q --upgrade "pip>=23.1"
fi

# Idempotent: the package is rebuilt only when a file it is built from changed. The stamp
# holds a hash of those files, then the extras installed with them.
stamp=.venv/virtmech-installed
source_hash="$(find CMakeLists.txt pyproject.toml src include python cmake -type f \
  -not -path '*/__pycache__/*' -print0 2>/dev/null | LC_ALL=C sort -z | xargs -0 sha256sum |
  sha256sum | cut -d' ' -f1)"
up_to_date=0
if [ -f "$stamp" ] && [ "$(head -n 1 "$stamp")" = "$source_hash" ] &&
  .venv/bin/python -c "import virtmech" 2>/dev/null; then
  up_to_date=1
  if [ -n "$extras" ] && ! tail -n +2 "$stamp" | grep -qx "$extras"; then
    # the same build; only the extra's dependencies are missing (read from pyproject.toml
    # with tomllib, Python >= 3.11; else reinstall)
    if deps="$(.venv/bin/python -c "
import sys, tomllib
with open('pyproject.toml', 'rb') as f:
    print('\\n'.join(tomllib.load(f)['project']['optional-dependencies'][sys.argv[1]]))
" "$extras" 2>/dev/null)"; then
      echo "setup: installing the $extras extra's dependencies"
      mapfile -t deps <<<"$deps"
      .venv/bin/python -m pip install -q "${deps[@]}"
      echo "$extras" >>"$stamp"
    else
      up_to_date=0
    fi
  fi
fi
if [ "$up_to_date" = 1 ]; then
  echo "setup: virtmech is up to date in .venv (no rebuild)"
  exit 0
fi
spec="."
[ -n "$extras" ] && spec=".[$extras]"
echo "setup: pip install $spec (builds the C++ core and its Python extension)"
.venv/bin/python -m pip install -q "$spec"
printf '%s\n%s\n' "$source_hash" "$extras" >"$stamp"

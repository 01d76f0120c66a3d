#!/usr/bin/env bash
# Sets up a fresh machine for virtmech: system build tools (Debian packages, when missing and
# we are root), a virtual environment in .venv, and virtmech installed into it with the
# extras named in $1 (e.g. "sim", "test" or "sim,view"). Idempotent: with nothing changed a
# second run neither rebuilds nor reinstalls (about a second), and an extra asked for after
# another only installs that extra's packages: the C++ core is built again only when a file
# it is built from changed. The first build takes about 3 minutes on two idle cores; its
# compile steps are shown as they go (pip's whole output: build/setup-pip.log).
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
  missing=()  # the extras asked for that this build has not had installed yet
  IFS=',' read -r -a asked <<<"$extras"
  for extra in "${asked[@]}"; do
    tail -n +2 "$stamp" | grep -qx "$extra" || missing+=("$extra")
  done
  if [ "${#missing[@]}" -gt 0 ]; then
    # the same build; only the extras' dependencies are missing (read from pyproject.toml
    # with tomllib, Python >= 3.11; else reinstall)
    if deps="$(.venv/bin/python -c "
import sys, tomllib
with open('pyproject.toml', 'rb') as f:
    extras = tomllib.load(f)['project']['optional-dependencies']
print('\\n'.join(d for name in sys.argv[1:] for d in extras[name]))
" "${missing[@]}" 2>/dev/null)"; then
      echo "setup: installing the ${missing[*]} extra's packages (the C++ core is not rebuilt)"
      mapfile -t deps <<<"$deps"
      .venv/bin/python -m pip install -q "${deps[@]}"
      printf '%s\n' "${missing[@]}" >>"$stamp"
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
log=build/setup-pip.log
mkdir -p build
echo "setup: pip install $spec: builds the C++ core and its Python extension (about 3 min on"
echo "setup: two idle cores, longer on a busy machine); its compile steps follow (all: $log)"
start=$SECONDS
set +e
# pip -v shows the build's output; of it, ninja's steps "[k/n] ..." (one a line when piped)
.venv/bin/python -m pip install -v "$spec" 2>&1 | tee "$log" |
  grep --line-buffered -E '^ *\[[0-9]+/[0-9]+\] ' | sed -u -E 's/^ */setup:   /'
rc=${PIPESTATUS[0]}
set -e
if [ "$rc" -ne 0 ]; then
  echo "setup: pip install $spec failed (exit status $rc); the end of $log:" >&2
  tail -n 40 "$log" >&2
  exit "$rc"
fi
echo "setup: built and installed in $(((SECONDS - start) / 60)) min $(((SECONDS - start) % 60)) s"
{ echo "$source_hash"; tr ',' '\n' <<<"$extras"; } >"$stamp"

# Shared by scripts/test and scripts/demo: install what is missing (Debian 12), configure, build.
# shellcheck shell=bash

SUBSTEP_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"

# Every package the build, the tests, the benchmark and the demo use.
SUBSTEP_PACKAGES=(
  cmake ninja-build g++ pkg-config
  libeigen3-dev libfcl-dev libccd-dev libassimp-dev
  libosmesa6-dev libstb-dev fonts-dejavu-core
  nlohmann-json3-dev libcli11-dev libgtest-dev libgmock-dev
  libdart-external-odelcpsolver-dev libbullet-dev
  ffmpeg gnuplot-nox parallel
)

# The fuzz build's compiler: clang 14 with libFuzzer and the sanitizer runtimes.
SUBSTEP_FUZZ_PACKAGES=(clang libclang-rt-14-dev)

# substep_install [extra packages...]
substep_install() {
  local missing=() p
  for p in "${SUBSTEP_PACKAGES[@]}" "$@"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  ((${#missing[@]} == 0)) && return 0
  if [[ $(id -u) -ne 0 ]]; then
    echo "substep needs these Debian packages, which are not installed: ${missing[*]}" >&2
    echo "Install them as root, then run this again:" >&2
    echo "  sudo apt-get update && sudo apt-get install -y --no-install-recommends ${missing[*]}" >&2
    exit 1
  fi
  echo "== installing ${#missing[@]} packages: ${missing[*]}"
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq
  apt-get install -y -qq --no-install-recommends "${missing[@]}"
}

# substep_build DIR [cmake options...]
substep_build() {
  local dir=$1
  shift
  cmake -S "$SUBSTEP_ROOT" -B "$dir" -G Ninja "$@" >"$dir.configure.log" 2>&1 || {
    cat "$dir.configure.log" >&2
    echo "cmake configure failed (log above, also in $dir.configure.log)" >&2
    exit 1
  }
  cmake --build "$dir" -j "$(nproc)"
}

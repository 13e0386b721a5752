# Shared by scripts/test and scripts/demo: install what is missing (Debian 12), configure, build.
# shellcheck shell=bash

SUBSTEP_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"

# Every package the build, the tests, the benchmark and the demo use. The install tests: cpack's
# Debian package needs dpkg-shlibdeps (dpkg-dev) and file; the sweep tests compare records with jq
# and run a single-node Slurm cluster (slurm-wlm: slurmctld, slurmd, the client; munge). ccache:
# a rebuild compiles only what changed (CMakeLists.txt).
SUBSTEP_PACKAGES=(
  cmake ninja-build g++ pkg-config ccache
  libeigen3-dev libfcl-dev libccd-dev libassimp-dev
  libosmesa6-dev libstb-dev libturbojpeg0-dev fonts-dejavu-core
  nlohmann-json3-dev libcli11-dev libgtest-dev libgmock-dev libcpp-httplib-dev
  libdart-external-odelcpsolver-dev libbullet-dev libode-dev libmujoco-dev libxxhash-dev
  ffmpeg gnuplot-nox parallel
  dpkg-dev file jq slurm-wlm munge
)

# The sanitizer and fuzz builds' compiler: clang 14 with libFuzzer and the sanitizer runtimes
# (clang compiles the instrumented code about three times faster than g++ at -O2 -g).
SUBSTEP_CLANG_PACKAGES=(clang libclang-rt-14-dev)

# The browser test's browser (about 470 MB installed), with node and npm from Debian when the
# machine has no node at all (substep_node_packages).
SUBSTEP_BROWSER_PACKAGES=(chromium)

# The Debian packages that bring node (18 or later) and npm, for those of the two not on PATH.
substep_node_packages() {
  command -v node >/dev/null || echo nodejs
  command -v npm >/dev/null || echo npm
}

# substep_npm DIR: the browser test's npm packages (playwright-core, from the committed lock) into
# DIR/node_modules; again only when the lock changed.
substep_npm() {
  local dir=$1 major
  major=$(node -p 'process.versions.node.split(".")[0]')
  if ((major < 18)); then
    echo "the browser test needs node 18 or later; this node is $(node --version)" >&2
    exit 1
  fi
  if cmp -s "$dir/package-lock.json" "$dir/node_modules/.substep-lock" 2>/dev/null; then return 0; fi
  echo "== npm ci in $dir (playwright-core)"
  (cd "$dir" && npm ci --no-audit --no-fund --loglevel=error) || {
    echo "npm ci failed in $dir" >&2
    exit 1
  }
  cp "$dir/package-lock.json" "$dir/node_modules/.substep-lock"
}

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

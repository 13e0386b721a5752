#!/usr/bin/env bash
# deb_test.sh BUILD: the Debian package (docs/install.md).
#   - `cpack -G DEB` in BUILD builds substep_<version>_<arch>.deb, its Depends computed from the
#     ELF files (dpkg-shlibdeps);
#   - `dpkg-deb --contents` lists the programs, the libraries, the CMake package, the pkg-config
#     files and the assets;
#   - apt accepts it: as root (CI) `apt-get install ./substep_*.deb` installs it on this machine,
#     `substep --version` and `substep scenes` run from /usr, and it is purged again at the end,
#     whatever happens (unless it was installed before the test); as another user it is unpacked
#     into a scratch root and run from there, and `apt-get install --simulate` resolves it.
set -euo pipefail
build=$(cd "${1:?usage: deb_test.sh BUILD}" && pwd)
work=$build/deb_test
rm -rf "$work"
mkdir -p "$work"
start=$SECONDS
fail() { echo "FAIL: $*" >&2; exit 1; }
step() { echo "== [$((SECONDS - start)) s] $*"; }

step "cpack -G DEB in $build"
(cd "$work" && cpack -G DEB --config "$build/CPackConfig.cmake" -B "$work" >"$work/cpack.log" 2>&1) ||
  { cat "$work/cpack.log"; fail "cpack failed"; }
debs=("$work"/substep_*.deb)
[[ -f ${debs[0]} && ${#debs[@]} -eq 1 ]] || fail "cpack made no single substep_*.deb: $(ls "$work")"
deb=${debs[0]}
echo "$(basename "$deb"): $(du -h "$deb" | cut -f1)"
dpkg-deb --field "$deb" Package Version Architecture Depends Recommends | tee "$work/fields.txt"
depends=$(dpkg-deb --field "$deb" Depends)
# shlibdeps: the libraries the ELF files need, with versions, beside the font.
for dep in libc6 'libstdc\+\+6' libosmesa6 'libassimp' 'libfcl' 'libbullet' 'libode' 'libmujoco' 'libturbojpeg' fonts-dejavu-core; do
  grep -Eq "(^|, )$dep" <<<"$depends" || fail "Depends lacks $dep: $depends"
done

step "dpkg-deb --contents"
dpkg-deb --contents "$deb" | awk '{print $NF}' | sed 's|^\./|/|' >"$work/contents.txt"
for f in /usr/bin/substep /usr/bin/substep-bench /usr/include/substep/physics/world.h \
  /usr/share/substep/assets/scenes/stack.json /usr/share/substep/assets/web/index.html \
  /usr/share/substep/assets/meshes/bowl.obj /usr/share/doc/substep/install.md; do
  grep -qx -- "$f" "$work/contents.txt" || fail "the package lacks $f"
done
for re in '/usr/lib/[^ ]*libsubstep-physics\.so\.[0-9.]*' '/usr/lib/[^ ]*libsubstep-render\.so\.[0-9.]*' \
  '/usr/lib/[^ ]*libsubstep-lab\.so\.[0-9.]*' '/usr/lib/[^ ]*cmake/substep/substepConfig\.cmake' \
  '/usr/lib/[^ ]*cmake/substep/substepTargets\.cmake' '/usr/lib/[^ ]*pkgconfig/substep-physics\.pc'; do
  grep -Eqx -- "$re" "$work/contents.txt" || fail "the package lacks $re"
done
echo "$(wc -l <"$work/contents.txt") entries: programs, libraries, headers, CMake package, pkg-config files, assets, docs"

if [[ $(id -u) -eq 0 ]]; then
  step "apt-get install $deb (root: on this machine)"
  if dpkg-query -W -f='${Status}' substep 2>/dev/null | grep -q "install ok installed"; then
    fail "a package substep is already installed here; remove it first (apt-get remove substep)"
  fi
  remove() { DEBIAN_FRONTEND=noninteractive apt-get purge -y -qq -o DPkg::Lock::Timeout=300 substep >"$work/remove.log" 2>&1 || cat "$work/remove.log"; }
  trap remove EXIT
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq -o DPkg::Lock::Timeout=300 "$deb" >"$work/apt.log" 2>&1 ||
    { cat "$work/apt.log"; fail "apt-get install $deb failed"; }
  substep=/usr/bin/substep
else
  step "unpacked into $work/root (not root: apt-get install --simulate, dpkg-deb -x)"
  apt-get install --simulate "$deb" >"$work/apt.log" 2>&1 || { cat "$work/apt.log"; fail "apt cannot install $deb"; }
  dpkg-deb -x "$deb" "$work/root"
  substep=$work/root/usr/bin/substep
  export LD_LIBRARY_PATH=$work/root/usr/lib
fi
cd /
version=$(env -u SUBSTEP_ASSETS "$substep" --version)
echo "$version"
[[ $version =~ ^substep\ [0-9]+\.[0-9]+\ \(commit\ [0-9a-f]{7,} ]] || fail "--version printed \"$version\""
scenes=$(env -u SUBSTEP_ASSETS "$substep" scenes)
want=$(dirname "$(dirname "$substep")")/share/substep/assets/scenes
grep -q "Scene files in $want" <<<"$scenes" || fail "substep scenes did not list $want: $(head -1 <<<"$scenes")"
grep -q "^  stack " <<<"$scenes" || fail "substep scenes did not list the scene stack"
echo "substep scenes: $(head -1 <<<"$scenes")"
step "passed"

#!/usr/bin/env bash
# install_test.sh BUILD SOURCE: substep installed into a temporary prefix and used from outside
# its source tree, as another project uses it (docs/install.md):
#   - `cmake --install BUILD --prefix P` lays out the programs, libraries, headers, CMake package,
#     pkg-config files, assets and docs; the installed programs load the installed libraries;
#   - the installed substep prints its version and a commit (also with no git on PATH), lists the
#     installed scenes and serves the installed page (a marker added to each proves which);
#   - the snapshot example, a separate CMake project, configured against P: its goldens match; with
#     a setting changed its ramp test fails and leaves a diff image; snapshot_update rewrites them;
#   - a small program built against substep::physics (CMake) and substep-physics (pkg-config)
#     steps stack.json and prints the top box's height.
# Works in BUILD/install_test (kept for a look after a failure; the diff image is there).
set -euo pipefail
build=$(cd "${1:?usage: install_test.sh BUILD SOURCE}" && pwd)
source=$(cd "${2:?usage: install_test.sh BUILD SOURCE}" && pwd)
work=$build/install_test
rm -rf "$work"
mkdir -p "$work"
prefix=$work/prefix
start=$SECONDS
server=
cleanup() { [[ -n $server ]] && kill "$server" 2>/dev/null && wait "$server" 2>/dev/null; return 0; }
trap cleanup EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }
step() { echo "== [$((SECONDS - start)) s] $*"; }

step "cmake --install $build --prefix $prefix"
cmake --install "$build" --prefix "$prefix" >"$work/install.log" || { cat "$work/install.log"; fail "cmake --install failed"; }
cmakedir=$(echo "$prefix"/lib*/cmake/substep)
libdir=$(dirname "$(dirname "$cmakedir")")
for f in bin/substep "${libdir#"$prefix"/}"/pkgconfig/substep-physics.pc "${libdir#"$prefix"/}"/pkgconfig/substep-render.pc \
  "${libdir#"$prefix"/}"/pkgconfig/substep-lab.pc include/substep/physics/world.h include/substep/render/session.h \
  include/substep/lab/sweep.h share/substep/assets/scenes/stack.json share/substep/assets/scenes/atlas \
  share/substep/assets/meshes/bowl.obj share/substep/assets/web/index.html share/substep/assets/snapshot_example/CMakeLists.txt \
  share/substep/sweep-slurm.sh share/doc/substep/README.md share/doc/substep/install.md; do
  [[ -e $prefix/$f ]] || fail "not installed: $f"
done
for f in substepConfig.cmake substepConfigVersion.cmake substepTargets.cmake SubstepSnapshotTest.cmake; do
  [[ -f $cmakedir/$f ]] || fail "not installed: $cmakedir/$f"
done
for lib in physics lab render; do
  ls "$libdir"/libsubstep-$lib.so.* >/dev/null 2>&1 || fail "no $libdir/libsubstep-$lib.so.*"
done
# The installed programs load the installed libraries (their RUNPATH is $ORIGIN/../lib), not the build's.
for exe in "$prefix"/bin/*; do
  ldd "$exe" | grep -q 'not found' && fail "$exe: $(ldd "$exe" | grep 'not found')"
  while read -r lib; do
    [[ $(realpath "$lib") == "$libdir"/* ]] || fail "$exe loads $lib, not the installed library"
  done < <(ldd "$exe" | awk '/libsubstep-/ {print $3}')
done
echo "installed: $(cd "$prefix" && find . -type f | wc -l) files; $(ls "$prefix"/bin | tr '\n' ' ')"

cd "$work"  # away from the source tree from here on
substep=$prefix/bin/substep
step "$substep --version"
version=$(env -i PATH=/usr/bin:/bin HOME="$work" "$substep" --version)
echo "$version"
[[ $version =~ ^substep\ [0-9]+\.[0-9]+\ \(commit\ [0-9a-f]{7,} ]] || fail "--version printed \"$version\""
# No git on PATH: the commit captured when the library was built.
nogit=$(env -i PATH="$prefix/bin" HOME="$work" "$substep" --version)
echo "$nogit (no git on PATH)"
[[ $nogit =~ ^substep\ [0-9]+\.[0-9]+\ \(commit\ [0-9a-f]{7,} ]] || fail "--version without git printed \"$nogit\""

step "substep scenes lists the installed scenes"
assets=$prefix/share/substep/assets
cp "$assets/scenes/stack.json" "$assets/scenes/install_marker.json"
scenes=$(env -u SUBSTEP_ASSETS "$substep" scenes)
grep -q "Scene files in $assets/scenes" <<<"$scenes" || fail "substep scenes did not list $assets/scenes: $(head -2 <<<"$scenes")"
grep -q install_marker <<<"$scenes" || fail "substep scenes did not list the installed install_marker.json"
echo "$(sed -n '/^Scene files/,/^Generators/p' <<<"$scenes" | grep -c '^  [a-z]') scene files listed from $assets/scenes"

step "substep serve serves the installed page"
echo "<!-- install-test-marker -->" >>"$assets/web/index.html"
env -u SUBSTEP_ASSETS "$substep" serve --port 0 >"$work/serve.log" 2>&1 &
server=$!
port=
for _ in $(seq 100); do
  port=$(sed -n 's|^substep serve: http://[^:]*:\([0-9]*\)/.*|\1|p' "$work/serve.log")
  [[ -n $port ]] && break
  kill -0 "$server" 2>/dev/null || { cat "$work/serve.log"; fail "substep serve exited"; }
  sleep 0.1
done
[[ -n $port ]] || { cat "$work/serve.log"; fail "substep serve printed no address"; }
get() {  # get PATH: the body of an HTTP/1.0 GET on the server (bash's /dev/tcp: no curl needed)
  exec 3<>"/dev/tcp/127.0.0.1/$port"
  printf 'GET %s HTTP/1.0\r\nHost: 127.0.0.1\r\n\r\n' "$1" >&3
  timeout 10 cat <&3
  exec 3<&-
}
get / | grep -q install-test-marker || fail "GET / on port $port did not serve $assets/web/index.html"
get /api/scenes | grep -q install_marker || fail "GET /api/scenes on port $port did not list the installed scenes"
kill "$server"
wait "$server" 2>/dev/null || true
server=
echo "port $port: the installed index.html and scene list"

step "the snapshot example against $prefix"
ex=$work/snapshot_example
cmake -S "$source/assets/snapshot_example" -B "$ex" -G Ninja -DCMAKE_PREFIX_PATH="$prefix" >"$work/example.log" ||
  { cat "$work/example.log"; fail "configuring the snapshot example failed"; }
found=$(sed -n 's/^substep_DIR:PATH=//p' "$ex/CMakeCache.txt")
[[ $found -ef $cmakedir ]] || fail "the example found substep in $found, not in $cmakedir"
cmake --build "$ex" >>"$work/example.log"
ctest --test-dir "$ex" --output-on-failure || fail "the snapshot example's goldens do not match"

step "a changed setting fails with a diff image"
changed=$work/snapshot_changed
cp -r "$source/assets/snapshot_example" "$changed"
sed -i 's/SETTINGS --size 320x180/SETTINGS --size 320x180 --slop 0.02/' "$changed/CMakeLists.txt"
grep -q -- '--slop 0.02' "$changed/CMakeLists.txt" || fail "could not change the example's settings"
cmake -S "$changed" -B "$changed/build" -G Ninja -DCMAKE_PREFIX_PATH="$prefix" >"$work/changed.log"
cmake --build "$changed/build" >>"$work/changed.log"
if ctest --test-dir "$changed/build" --output-on-failure >"$work/changed.ctest.log" 2>&1; then
  cat "$work/changed.ctest.log"
  fail "with --slop 0.02 the snapshot tests still pass"
fi
grep -E 'MISMATCH|tests passed|Failed' "$work/changed.ctest.log" || true
grep -q 'snapshot_ramp .*Failed' "$work/changed.ctest.log" || fail "snapshot_ramp did not fail with --slop 0.02"
diff=$changed/build/snapshots/snapshot_ramp/ramp@1.5.diff.png
[[ $(head -c 8 "$diff" 2>/dev/null | od -An -tx1 | tr -d ' \n') == 89504e470d0a1a0a ]] || fail "no diff image $diff"
cp "$diff" "$changed/build/snapshots/snapshot_ramp/ramp@1.5.actual.png" "$work/"
echo "diff image: $diff (kept as $work/ramp@1.5.diff.png: a match after the update removes it)"
cmake --build "$changed/build" --target snapshot_update >"$work/update.log" || { cat "$work/update.log"; fail "snapshot_update failed"; }
grep -q rewritten "$work/update.log" || fail "snapshot_update rewrote no golden: $(cat "$work/update.log")"
ctest --test-dir "$changed/build" --output-on-failure >"$work/updated.ctest.log" 2>&1 ||
  { cat "$work/updated.ctest.log"; fail "the goldens snapshot_update wrote do not match"; }
echo "snapshot_update rewrote $(grep -c rewritten "$work/update.log") goldens; they match"

step "a program built against substep::physics"
cmake -S "$source/tests/install/top_box" -B "$work/top_box" -G Ninja -DCMAKE_BUILD_TYPE=Release \
  -DCMAKE_PREFIX_PATH="$prefix" >"$work/top_box.log" || { cat "$work/top_box.log"; fail "configuring top_box failed"; }
cmake --build "$work/top_box" >>"$work/top_box.log" || { cat "$work/top_box.log"; fail "building top_box failed"; }
height=$("$work/top_box/top_box" "$assets/scenes/stack.json" 2)
echo "stack.json after 2 s: the top box's centre at $height m (resting: 4.5 m)"
awk -v h="$height" 'BEGIN { exit !(h > 4.45 && h < 4.55) }' || fail "top box at $height m, not about 4.5 m"

step "the same program built with pkg-config (substep-physics)"
export PKG_CONFIG_PATH=$libdir/pkgconfig
# shellcheck disable=SC2046
g++ -std=c++17 -O1 "$source/tests/install/top_box/main.cpp" $(pkg-config --cflags --libs substep-physics) \
  -Wl,-rpath,"$libdir" -o "$work/top_box_pc" || fail "building top_box with pkg-config failed"
height_pc=$("$work/top_box_pc" "$assets/scenes/stack.json" 2)
[[ $height_pc == "$height" ]] || fail "the pkg-config build prints $height_pc, the CMake build $height"
pkg-config --exists substep-render substep-lab || fail "pkg-config does not resolve substep-render and substep-lab"
echo "pkg-config build: $height_pc m; substep-render and substep-lab resolve"
step "passed"

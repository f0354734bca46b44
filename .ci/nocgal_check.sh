#!/usr/bin/env bash
# CGAL is a test and benchmark dependency only: a user builds the product (tinstream,
# tinstream-server, tinstream-viewer) without it. This checks that in seconds instead of a fourth
# full build: CMake configures with CGAL hidden and the tests off, the three binaries are in the
# plan with no CGAL anywhere in it, and no product source includes a CGAL header (so they compile
# exactly as in the release tree, which CI builds).
set -euo pipefail
cd "$(dirname "$0")/.."
dir=build-nocgal
rm -rf "$dir"
mkdir -p "$dir"
cmake -S . -B "$dir" -G Ninja -DCMAKE_BUILD_TYPE=Release -DCMAKE_DISABLE_FIND_PACKAGE_CGAL=ON \
  -DTINSTREAM_BUILD_TESTS=OFF >"$dir/configure.log" 2>&1 || { cat "$dir/configure.log"; echo "nocgal: configure failed"; exit 1; }
for target in tinstream tinstream-server tinstream-viewer; do
  ninja -C "$dir" -n "$target" >/dev/null || { echo "nocgal: no plan for $target"; exit 1; }
done
if grep -q CGAL "$dir/build.ninja"; then
  echo "nocgal: the CGAL-less build still names CGAL:"; grep -m5 CGAL "$dir/build.ninja" | cut -c1-200; exit 1
fi
product=$(git grep -l -E '#include *[<"]CGAL/' -- '*.cpp' '*.hpp' ':!tests/' ':!bench/' ':!*/tests/*' || true)
if [[ -n $product ]]; then
  echo "nocgal: product sources include CGAL:"; echo "$product"; exit 1
fi
rm -rf "$dir"
echo "nocgal: the product configures and plans without CGAL; no product source includes it"

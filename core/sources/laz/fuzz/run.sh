#!/usr/bin/env bash
# Runs the LAZ fuzzer with the real LAZ files of ../shared/data and the LASzip-written test
# files (core/sources/laz/tests/data) as its seed corpus.
#   core/sources/laz/fuzz/run.sh [FUZZER] [SECONDS]
# FUZZER defaults to build-fuzz/bin/laz_fuzzer (scripts/fuzz.sh --only laz_fuzzer builds it, or
# cmake -DTINSTREAM_FUZZ=ON with clang); the corpus grows
# in a temporary directory (removed at the end; crashes are written to the working directory).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
fuzzer=${1:-build-fuzz/bin/laz_fuzzer}
seconds=${2:-60}
data=${TINSTREAM_SHARED_DATA:-$here/../../../../../shared/data}
corpus=$(mktemp -d)
trap 'rm -rf "$corpus"' EXIT
cp "$data"/*.laz "$here"/corpus/* "$here"/../tests/data/*.laz "$corpus"/
"$fuzzer" "$corpus" -max_total_time="$seconds" -max_len=4000000 -rss_limit_mb=2048 -timeout=30

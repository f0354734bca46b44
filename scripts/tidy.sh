#!/usr/bin/env bash
# Runs the curated .clang-tidy over our sources using the build's compile_commands.json.
set -euo pipefail
build=${1:-build}
files=$(git ls-files 'core/*.cpp' 'server/*.cpp' 'client/*.cpp')
run-clang-tidy -p "$build" -quiet $files 2>/dev/null || clang-tidy -p "$build" --quiet $files

#!/usr/bin/env bash
# The main job on the built-in sample: until the pipeline lands, show what the build contains.
set -euo pipefail
build=${1:-build}
"$build/bin/tinstream" modules

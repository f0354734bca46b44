# tinstream — the two set-up commands and the developer targets.
#   make demo     install deps, build, ingest the built-in sample, serve it, show it
#   make test     install deps, then everything CI checks (.ci/pipeline.sh): the Release (-O3)
#                 build and the whole suite, the ASan+UBSan build and the whole suite, the TSan
#                 build and the threaded suites, format-check, clang-tidy, the fuzzers 20 s each
# Developer targets: build, check (the suite in $(BUILD), no install), release, asan, tsan, fuzz,
# format, format-check, tidy, crash (the crash-safety harnesses, 200 kills), bench.
BUILD ?= build
JOBS  ?= $(shell nproc)
CMAKE_FLAGS ?=
# CI's trees unity-build the test executables (TINSTREAM_UNITY: test files compiled 8 to a TU;
# the product stays one object per file but in the ASan tree): test objects 346 -> ~219 CPU s in
# the Release tree, 658 -> 368 in the ASan tree, 182 -> 106 in the TSan tree (2026-11-28,
# docs/SECURITY.md "CI"). Tidy reads a configured-only tree batched the same way, the product
# too (.ci/pipeline.sh; scripts/tidy.sh checks each batch once).
UNITY_FLAGS = -DTINSTREAM_UNITY=ON
# Sanitizer builds: optimised (-O1) with line tables (-g1: file:line in every report, less to
# compile than full debug info) and the asserts on (no NDEBUG).
SAN_FLAGS = -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1" \
            -DCMAKE_C_FLAGS_RELWITHDEBINFO="-O1 -g1" $(UNITY_FLAGS)
# The suites with threads of their own (worker pools, the store queue, the server's io threads,
# the client's download threads against the real server; neither client suite makes a GL context).
# Longest first (.ci/run_tests.sh runs two at a time, in this order; TSan seconds in the 5f7a21d
# run: lod 219, ingest 196, triangulate 163, server 45, imagery 17, subdivide 14, the rest < 7), so
# the two slots end together: 359 s instead of ~371 by those figures.
TSAN_TARGETS = lod_tests ingest_tests triangulate_tests server_tests imagery_tests \
               subdivide_tests transform_tests store_tests client_tests client_integration_tests \
               base_tests

.PHONY: all deps build test check demo release asan tsan fuzz format format-check tidy crash bench clean

all: build

deps:
	bash scripts/install-deps.sh

$(BUILD)/build.ninja:
	cmake -S . -B $(BUILD) -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo $(CMAKE_FLAGS)

build: $(BUILD)/build.ninja
	cmake --build $(BUILD) -j $(JOBS)

check: build
	ctest --test-dir $(BUILD) --output-on-failure -j $(JOBS)

test: deps
	bash .ci/pipeline.sh

demo: deps build
	bash scripts/demo.sh $(BUILD)

# What docker/ ships: Release (-O3), and the whole suite on it.
release:
	$(MAKE) check BUILD=build-release CMAKE_FLAGS="-DCMAKE_BUILD_TYPE=Release $(UNITY_FLAGS)"

# The ASan tree unity-builds the product too (TINSTREAM_UNITY_PRODUCT; nothing ships from it):
# its product objects 832 -> 677 CPU s.
asan:
	LSAN_OPTIONS="suppressions=$(CURDIR)/.ci/lsan.supp $${LSAN_OPTIONS:-}" \
	  $(MAKE) check BUILD=build-asan CMAKE_FLAGS='-DTINSTREAM_ASAN=ON $(SAN_FLAGS) -DTINSTREAM_UNITY_PRODUCT=ON'

tsan: build-tsan/build.ninja
	cmake --build build-tsan -j $(JOBS) --target $(TSAN_TARGETS) tinstream tinstream-server
	bash .ci/run_tests.sh build-tsan $(TSAN_TARGETS)

build-tsan/build.ninja:
	cmake -S . -B build-tsan -G Ninja -DTINSTREAM_TSAN=ON $(SAN_FLAGS)

fuzz:
	bash scripts/fuzz.sh --seconds $${FUZZ_SECONDS:-60} $${FUZZ_SEED:+--seed $$FUZZ_SEED}

format: $(BUILD)/build.ninja
	cmake --build $(BUILD) --target format

format-check: $(BUILD)/build.ninja
	cmake --build $(BUILD) --target format-check

tidy: $(BUILD)/build.ninja
	bash scripts/tidy.sh $(BUILD)

crash: build
	bash tests/cli/crash_safety.sh --build $(BUILD) --kills $${KILLS:-200}
	bash tests/cli/admin_crash_safety.sh --build $(BUILD) --kills $${KILLS:-200}

bench:
	bash bench/run.sh

clean:
	rm -rf $(BUILD) build-release build-asan build-tsan build-fuzz

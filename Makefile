# tinstream — the two set-up commands and the developer targets.
#   make demo     install deps, build, ingest the built-in sample, serve it, show it
#   make test     install deps, build, run every test (what CI runs)
# Developer targets: build, check (tests without install), asan, tsan, format, format-check, tidy, bench.
BUILD ?= build
JOBS  ?= $(shell nproc)
CMAKE_FLAGS ?=

.PHONY: all deps build test check demo asan tsan format format-check tidy bench clean

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
	$(MAKE) check

demo: deps build
	bash scripts/demo.sh $(BUILD)

asan:
	$(MAKE) check BUILD=build-asan CMAKE_FLAGS="-DTINSTREAM_ASAN=ON -DCMAKE_BUILD_TYPE=Debug"

tsan:
	$(MAKE) check BUILD=build-tsan CMAKE_FLAGS="-DTINSTREAM_TSAN=ON"

format: $(BUILD)/build.ninja
	cmake --build $(BUILD) --target format

format-check: $(BUILD)/build.ninja
	cmake --build $(BUILD) --target format-check

tidy: $(BUILD)/build.ninja
	bash scripts/tidy.sh $(BUILD)

bench:
	bash bench/run.sh

clean:
	rm -rf $(BUILD) build-asan build-tsan

# horizonreg: `make demo` installs what is missing, builds and runs the demo;
# `make test` builds and runs every test.
BUILD ?= build
JOBS ?= $(shell nproc)
CMAKE_FLAGS ?= -DCMAKE_BUILD_TYPE=Release

.PHONY: all deps test-deps build demo test bench asan clean

all: build

deps:
	@scripts/install_deps.sh

test-deps:
	@scripts/install_deps.sh --test

build: deps
	cmake -S . -B $(BUILD) $(CMAKE_FLAGS)
	cmake --build $(BUILD) -j $(JOBS)

demo: build
	$(BUILD)/horizonreg demo --output-dir out

test: test-deps build
	cd $(BUILD) && ctest --output-on-failure -j $(JOBS)

bench: build
	$(BUILD)/horizon_bench
	$(BUILD)/skyline_bench
	$(BUILD)/register_bench
	$(BUILD)/track_bench
	$(BUILD)/batch_bench
	scripts/bench_process.sh $(BUILD)/horizonreg
	scripts/bench_grass_points.sh $(BUILD)/horizonreg || [ $$? -eq 77 ]

asan: test-deps
	$(MAKE) test BUILD=build-asan CMAKE_FLAGS="-DCMAKE_BUILD_TYPE=RelWithDebInfo -DHORIZONREG_SANITIZE=ON"

clean:
	rm -rf $(BUILD) build-asan out

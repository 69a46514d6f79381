# Top-level entry points. Every target installs what it needs first (tools/install-deps is quiet when done).
# Host code builds with CMake+Ninja into build/cmake, binaries into build/bin; the AVR firmware into build/firmware.
.PHONY: all deps configure host programs firmware test sanitize bench fuzz demo flash deb clean soak deps-arm64 \
        programs-arm64 test-arm64

BUILD      := build
CMAKE_DIR  := $(BUILD)/cmake
JOBS       ?= 2
FUZZ_SECONDS ?= 60
SOAK_PICKS ?= 1000
PORT       ?= /dev/ttyACM0
ARCH       ?= $(shell dpkg --print-architecture)
# ccache keys on paths relative to the checkout, so clones and worktrees share one cache.
export CCACHE_BASEDIR := $(CURDIR)
export CCACHE_NOHASHDIR := true

all: host firmware

deps:
	@tools/install-deps

configure: deps
	@cmake -S . -B $(CMAKE_DIR) -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo >/dev/null

# Everything CMake builds: the programs, the test and benchmark executables.
host: configure
	@cmake --build $(CMAKE_DIR) -j $(JOBS)

# The programs alone (what the demo and the package run), no test or benchmark executable: a first build in
# minutes. `make test` builds the rest.
PROGRAMS := rbx1 rbx1d rbx1-simfw rbx1-world
programs: configure
	@cmake --build $(CMAKE_DIR) -j $(JOBS) --target $(PROGRAMS)

firmware: deps
	@tools/build-firmware

# ctest runs everything: GoogleTest suites, pytest suites, the protocol harness against both simulators,
# the fuzz smoke, and the end-to-end pick tests.
test: host firmware
	@ctest --test-dir $(CMAKE_DIR) --output-on-failure -j $(JOBS)

# The host's GoogleTest suites under ASan+UBSan (build/asan), the daemon, link and GPIO ones under TSan (build/tsan).
sanitize: deps
	@tools/sanitize

bench: host firmware
	@tools/bench/firmware
	@tools/bench/motion
	@tools/bench/link-window
	@tools/bench/crc-avr
	@tools/bench/perception-speed
	@tools/bench/perception-accuracy
	@tools/bench/perception-twins
	@tools/bench/perception-corpus
	@tools/bench/light-sweep
	@tools/bench/daemon-latency
	@tools/bench/bus
	@tools/bench/console-live
	@tools/bench/world
	@tools/bench/world --classes new --teach --configs baseline_no_errors,workspace_calibration --worlds 10 --zero-worlds 10 --objects 4-6
	@tools/bench/mqtt
	@tools/bench/history
	@tools/bench/jobs

fuzz: deps
	@protocol/fuzz/run $(FUZZ_SECONDS)
	@host/mqtt/fuzz/run $(FUZZ_SECONDS)

demo: programs firmware
	@tools/demo
	@echo
	@tools/demo --world

# The fault campaign (tools/soak/README.md): SOAK_PICKS picks under line faults, outages, vanished ports, daemon
# kills and firmware power cycles; the summary also goes to build/soak/summary.json.
soak: host firmware
	@tools/soak/soak --picks $(SOAK_PICKS) --progress 25 --json $(BUILD)/soak/summary.json

flash: firmware
	@tools/flash $(PORT)

# build/deb/rbx1_VERSION_ARCH.deb: the host side as a Debian package (tools/deb/README.md); ARCH=arm64 cross-builds
# it for the arm's arm64 computer (tools/cross/README.md).
ifeq ($(ARCH),arm64)
deb: programs-arm64 programs firmware
	@tools/deb/build-deb --arch arm64
else
deb: programs firmware
	@tools/deb/build-deb
endif

# arm64 (tools/cross/README.md): the cross compiler and emulator, the arm64 library root build/arm64-sysroot, the
# programs cross-built into build/arm64/cmake/bin (niced: the machine is shared; the same optimisation as here, without
# the debug information the package strips anyway: a quarter less compile time), and their checks under qemu against
# this machine's build (detections, a whole pick against rbx1-simfw).
deps-arm64: deps
	@tools/install-deps tools/apt-packages-arm64.txt
	@tools/cross/arm64-sysroot

programs-arm64: deps-arm64
	@nice -n 10 cmake -S . -B $(BUILD)/arm64/cmake -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
	  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O2 -DNDEBUG" -DCMAKE_C_FLAGS_RELWITHDEBINFO="-O2 -DNDEBUG" \
	  -DCMAKE_TOOLCHAIN_FILE=$(CURDIR)/tools/cross/aarch64.cmake >/dev/null
	@nice -n 10 cmake --build $(BUILD)/arm64/cmake -j $(JOBS) --target rbx1 rbx1d

test-arm64: programs-arm64 programs firmware
	@tools/cross/test-arm64

clean:
	rm -rf $(BUILD)

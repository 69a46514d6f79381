# Top-level entry points. Every target installs what it needs first (tools/install-deps is quiet when done).
# Host code builds with CMake+Ninja into build/cmake, binaries into build/bin; the AVR firmware into build/firmware.
.PHONY: all deps host firmware test sanitize bench fuzz demo flash deb clean soak

BUILD      := build
CMAKE_DIR  := $(BUILD)/cmake
JOBS       ?= 2
FUZZ_SECONDS ?= 60
SOAK_PICKS ?= 1000
PORT       ?= /dev/ttyACM0
# ccache keys on paths relative to the checkout, so clones and worktrees share one cache.
export CCACHE_BASEDIR := $(CURDIR)
export CCACHE_NOHASHDIR := true

all: host firmware

deps:
	@tools/install-deps

host: deps
	@cmake -S . -B $(CMAKE_DIR) -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo >/dev/null
	@cmake --build $(CMAKE_DIR) -j $(JOBS)

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
	@tools/bench/perception-corpus
	@tools/bench/daemon-latency
	@tools/bench/bus
	@tools/bench/console-live
	@tools/bench/world
	@tools/bench/history
	@tools/bench/jobs

fuzz: deps
	@protocol/fuzz/run $(FUZZ_SECONDS)

demo: host firmware
	@tools/demo
	@echo
	@tools/demo --world

# The fault campaign (tools/soak/README.md): SOAK_PICKS picks under line faults, outages, vanished ports, daemon
# kills and firmware power cycles; the summary also goes to build/soak/summary.json.
soak: host firmware
	@tools/soak/soak --picks $(SOAK_PICKS) --progress 25 --json $(BUILD)/soak/summary.json

flash: firmware
	@tools/flash $(PORT)

# build/deb/rbx1_VERSION_ARCH.deb: the host side as a Debian package (tools/deb/README.md).
deb: host firmware
	@tools/deb/build-deb

clean:
	rm -rf $(BUILD)

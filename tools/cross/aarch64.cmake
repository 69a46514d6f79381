# CMake toolchain file for arm64 (aarch64-linux-gnu): Debian's cross compiler (crossbuild-essential-arm64) against
# the arm64 library root made by tools/cross/arm64-sysroot (build/arm64-sysroot unless RBX1_SYSROOT says otherwise).
# Used by `make deb ARCH=arm64` and `make test-arm64` (tools/cross/README.md).
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR aarch64)
set(CMAKE_LIBRARY_ARCHITECTURE aarch64-linux-gnu)
set(CMAKE_C_COMPILER aarch64-linux-gnu-gcc)
set(CMAKE_CXX_COMPILER aarch64-linux-gnu-g++)

if(NOT RBX1_SYSROOT)
  if(DEFINED ENV{RBX1_SYSROOT})
    set(RBX1_SYSROOT $ENV{RBX1_SYSROOT})
  else()
    get_filename_component(RBX1_SYSROOT ${CMAKE_CURRENT_LIST_DIR}/../../build/arm64-sysroot ABSOLUTE)
  endif()
endif()
if(NOT EXISTS ${RBX1_SYSROOT}/usr/lib/aarch64-linux-gnu)
  message(FATAL_ERROR "no arm64 library root at ${RBX1_SYSROOT}: run tools/cross/arm64-sysroot")
endif()
set(RBX1_SYSROOT ${RBX1_SYSROOT} CACHE PATH "the arm64 library root (tools/cross/arm64-sysroot)")
set(CMAKE_SYSROOT ${RBX1_SYSROOT})
set(CMAKE_FIND_ROOT_PATH ${RBX1_SYSROOT})
# Programs (avr-gcc, python3) from this machine; headers, libraries and CMake packages from the arm64 root only.
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE ONLY)
# pkg-config (libgpiod, cpp-httplib, simavr) reads the arm64 root's .pc files and prefixes their paths with it.
set(ENV{PKG_CONFIG_SYSROOT_DIR} ${RBX1_SYSROOT})
set(ENV{PKG_CONFIG_LIBDIR} ${RBX1_SYSROOT}/usr/lib/aarch64-linux-gnu/pkgconfig:${RBX1_SYSROOT}/usr/share/pkgconfig)
# The libraries' own dependencies (OpenCV's LAPACK, GDAL, ...) resolve inside the root when linking.
set(CMAKE_EXE_LINKER_FLAGS_INIT
    "-Wl,-rpath-link,${RBX1_SYSROOT}/usr/lib/aarch64-linux-gnu -Wl,-rpath-link,${RBX1_SYSROOT}/lib/aarch64-linux-gnu")
# Test executables are not run at build time to list their tests (they are not built for arm64 anyway).
set(CMAKE_GTEST_DISCOVER_TESTS_DISCOVERY_MODE PRE_TEST)

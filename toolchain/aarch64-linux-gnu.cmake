# Cross build for the Raspberry Pi 4 and 5 (64-bit Raspberry Pi OS or Debian 12 arm64) with
# Debian's cross compiler, against the arm64 sysroot toolchain/arm64_sysroot.sh makes. Tests run
# under qemu-aarch64 with the sysroot as its library root.
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR aarch64)
set(CMAKE_C_COMPILER aarch64-linux-gnu-gcc)
set(CMAKE_CXX_COMPILER aarch64-linux-gnu-g++)
set(CMAKE_LIBRARY_ARCHITECTURE aarch64-linux-gnu)

if(NOT CALBOX_ARM64_SYSROOT)
  set(CALBOX_ARM64_SYSROOT "${CMAKE_CURRENT_LIST_DIR}/../build/arm64-sysroot")
endif()
get_filename_component(CALBOX_ARM64_SYSROOT "${CALBOX_ARM64_SYSROOT}" ABSOLUTE)
if(NOT EXISTS "${CALBOX_ARM64_SYSROOT}/.calbox-sysroot")
  message(FATAL_ERROR "no arm64 sysroot at ${CALBOX_ARM64_SYSROOT}: toolchain/calbox.sh build --preset arm64 makes it")
endif()
set(CMAKE_SYSROOT "${CALBOX_ARM64_SYSROOT}")
set(CMAKE_FIND_ROOT_PATH "${CALBOX_ARM64_SYSROOT}")
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE ONLY)
# pkg-config reads the sysroot's .pc files and prefixes their paths with it.
set(ENV{PKG_CONFIG_DIR} "")
set(ENV{PKG_CONFIG_LIBDIR} "${CALBOX_ARM64_SYSROOT}/usr/lib/aarch64-linux-gnu/pkgconfig:${CALBOX_ARM64_SYSROOT}/usr/share/pkgconfig")
set(ENV{PKG_CONFIG_SYSROOT_DIR} "${CALBOX_ARM64_SYSROOT}")
# The unpacked sysroot keeps /lib and /usr/lib apart (Debian's merged /usr is made by an
# installer, not by the packages): the linker is told where the libraries' own needs are.
set(CMAKE_EXE_LINKER_FLAGS_INIT
    "-Wl,-rpath-link,${CALBOX_ARM64_SYSROOT}/lib/aarch64-linux-gnu -Wl,-rpath-link,${CALBOX_ARM64_SYSROOT}/usr/lib/aarch64-linux-gnu")
set(CMAKE_SHARED_LINKER_FLAGS_INIT "${CMAKE_EXE_LINKER_FLAGS_INIT}")
set(CMAKE_CROSSCOMPILING_EMULATOR qemu-aarch64 -L "${CALBOX_ARM64_SYSROOT}")

# Cross toolchain for AArch64 Linux (Debian's gcc-aarch64-linux-gnu), with tests run under
# qemu-user. Use with -DWEFT_KERNELS_ONLY=ON: only the core, CPU dispatch and kernels (and their
# tests) are built, so no target libraries beyond libc/libm are needed.
#
#   cmake -S . -B build-arm -DCMAKE_TOOLCHAIN_FILE=cmake/aarch64-linux-gnu.cmake -DWEFT_KERNELS_ONLY=ON
#   cmake --build build-arm -j2 && ctest --test-dir build-arm
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR aarch64)

set(CMAKE_C_COMPILER aarch64-linux-gnu-gcc)
set(CMAKE_CXX_COMPILER aarch64-linux-gnu-g++)

set(WEFT_AARCH64_SYSROOT /usr/aarch64-linux-gnu)
set(CMAKE_FIND_ROOT_PATH ${WEFT_AARCH64_SYSROOT})
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE ONLY)

# Test executables run through qemu with the target's loader and libraries.
set(CMAKE_CROSSCOMPILING_EMULATOR qemu-aarch64;-L;${WEFT_AARCH64_SYSROOT})
set(WEFT_TEST_EMULATOR qemu-aarch64;-L;${WEFT_AARCH64_SYSROOT} CACHE STRING "Runs cross-built tests")

# runtime/CMakeLists.txt looks up the header-only cglm unconditionally; the kernels-only build
# includes no cglm header. Pointing the lookup at the target's own include directory satisfies it
# without putting the host's /usr/include (x86 glibc headers) on the cross compiler's path.
set(CGLM_INCLUDE_DIR ${WEFT_AARCH64_SYSROOT}/include CACHE PATH "cglm headers (unused in kernels-only builds)")

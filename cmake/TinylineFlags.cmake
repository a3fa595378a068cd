# SPDX-License-Identifier: Apache-2.0
# One place for compiler flags: every project target calls
# tinyline_apply_flags(), which adds the warning set, warnings-as-errors and
# the sanitizer chosen with -DTINYLINE_SANITIZE=...

set(TINYLINE_WARNINGS -Wall -Wextra -Wpedantic -Werror)
# GCC 12's middle-end warnings (-Wrestrict, -Wstringop-overflow,
# -Wstringop-overread, -Warray-bounds) give false positives inside libstdc++'s
# std::string and std::vector when optimising at -O3, a Release build (GCC bug
# 105651 is the -Wrestrict one; seen here in bus/dds and the bag tests). Keep
# them warnings in Release so a user's Release build does not fail on the
# standard library's code; the -O2 builds (RelWithDebInfo, CI) keep -Werror.
if(CMAKE_CXX_COMPILER_ID STREQUAL "GNU" AND CMAKE_CXX_COMPILER_VERSION VERSION_LESS 13)
  list(APPEND TINYLINE_WARNINGS
       "$<$<CONFIG:Release>:-Wno-error=restrict;-Wno-error=stringop-overflow;-Wno-error=stringop-overread;-Wno-error=array-bounds>")
endif()

set(_tl_san_flags "")
if(TINYLINE_SANITIZE)
  string(REPLACE ";" "," _tl_san_list "${TINYLINE_SANITIZE}")
  set(_tl_san_flags -fsanitize=${_tl_san_list} -fno-omit-frame-pointer)
  if("undefined" IN_LIST TINYLINE_SANITIZE)
    list(APPEND _tl_san_flags -fno-sanitize-recover=undefined)
  endif()
endif()

function(tinyline_apply_flags target)
  target_compile_options(${target} PRIVATE ${TINYLINE_WARNINGS} ${_tl_san_flags})
  if(_tl_san_flags)
    target_link_options(${target} PRIVATE ${_tl_san_flags})
  endif()
endfunction()

# The linker: gold where the toolchain has it (binutils ships it). Our -g
# binaries link in about half the CPU time of the default ld.bfd
# (docs/developing.md, "Build time"). -DTINYLINE_LINKER=default keeps the
# compiler's default; any name -fuse-ld= takes (lld, mold) works too.
set(TINYLINE_LINKER "gold" CACHE STRING "Linker for -fuse-ld=, or 'default'")
if(NOT TINYLINE_LINKER STREQUAL "default")
  include(CheckLinkerFlag)
  check_linker_flag(CXX "-fuse-ld=${TINYLINE_LINKER}" TINYLINE_HAVE_LINKER_${TINYLINE_LINKER})
  if(TINYLINE_HAVE_LINKER_${TINYLINE_LINKER})
    add_link_options(-fuse-ld=${TINYLINE_LINKER})
  else()
    message(STATUS "tinyline: linker '${TINYLINE_LINKER}' not usable here; using the compiler's default")
  endif()
endif()

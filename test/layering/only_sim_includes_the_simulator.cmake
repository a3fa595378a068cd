# SPDX-License-Identifier: Apache-2.0
# Fails when a package's own code includes the simulator: every file under a
# src/, include/ or nodes/ folder of any package but sim/ (its simulation room
# <pkg>/sim/, evaluation harnesses under <pkg>/eval/, tests and benchmarks may;
# so may tools/, the top: the one executable that registers every package's
# nodes, the simulator's among them). Run as
#   cmake -DROOT=<source dir> -P only_sim_includes_the_simulator.cmake
if(NOT ROOT)
  message(FATAL_ERROR "ROOT (the source tree) is required")
endif()

file(GLOB _top LIST_DIRECTORIES true RELATIVE ${ROOT} ${ROOT}/*)
set(_offenders "")
foreach(pkg IN LISTS _top)
  if(NOT IS_DIRECTORY ${ROOT}/${pkg} OR NOT EXISTS ${ROOT}/${pkg}/CMakeLists.txt)
    continue()
  endif()
  if(pkg MATCHES "^(sim|test|bench|tools|build.*)$")
    continue()
  endif()
  file(GLOB_RECURSE _files RELATIVE ${ROOT} ${ROOT}/${pkg}/*.hpp ${ROOT}/${pkg}/*.cpp ${ROOT}/${pkg}/*.h ${ROOT}/${pkg}/*.cc)
  foreach(f IN LISTS _files)
    # Only the package's own layers: src/, include/, nodes/ at any depth
    # (bus/bag/src, ...), never under sim/, eval/, test/ or fuzz/.
    if(NOT f MATCHES "/(src|include|nodes)/" OR f MATCHES "^[^/]+/(.*/)?(sim|eval|test|fuzz)/")
      continue()
    endif()
    file(STRINGS ${ROOT}/${f} _hits REGEX "^[ \t]*#[ \t]*include[ \t]*[<\"]sim/")
    foreach(h IN LISTS _hits)
      string(STRIP "${h}" h)
      list(APPEND _offenders "${f}: ${h}")
    endforeach()
  endforeach()
endforeach()

if(_offenders)
  list(JOIN _offenders "\n  " _list)
  message(FATAL_ERROR "only sim/ (and evaluation harnesses, tests, benchmarks) may include the simulator:\n  ${_list}")
endif()
message(STATUS "no package outside sim/ includes the simulator")

# SPDX-License-Identifier: Apache-2.0
# Fails when the simulator includes an application package: sim/ is the world,
# its sensors and devices and their generic nodes, a floor below
# laser_clustering, tomato_reasoning and hydrus_fitting, whose simulated nodes,
# scenes and scorers live in their own <pkg>/sim/ and <pkg>/eval/ (sim/test/
# may include them). Run as
#   cmake -DROOT=<source dir> -P sim_includes_no_application.cmake
if(NOT ROOT)
  message(FATAL_ERROR "ROOT (the source tree) is required")
endif()

set(_applications laser_clustering tomato_reasoning hydrus_fitting)
list(JOIN _applications "|" _alternatives)
file(GLOB_RECURSE _files RELATIVE ${ROOT} ${ROOT}/sim/*.hpp ${ROOT}/sim/*.cpp ${ROOT}/sim/*.h ${ROOT}/sim/*.cc)
set(_offenders "")
foreach(f IN LISTS _files)
  if(f MATCHES "^sim/test/")
    continue()
  endif()
  file(STRINGS ${ROOT}/${f} _hits REGEX "^[ \t]*#[ \t]*include[ \t]*[<\"](${_alternatives})/")
  foreach(h IN LISTS _hits)
    string(STRIP "${h}" h)
    list(APPEND _offenders "${f}: ${h}")
  endforeach()
endforeach()

if(_offenders)
  list(JOIN _offenders "\n  " _list)
  message(FATAL_ERROR "sim/ includes no application package (${_applications}); move the file to the "
                      "package's sim/ or eval/:\n  ${_list}")
endif()
message(STATUS "sim/ includes no application package")

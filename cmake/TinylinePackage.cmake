# SPDX-License-Identifier: Apache-2.0
# Helpers that make every package look the same:
#
#   tinyline_core_library(<name> SOURCES ... [DEPS ...])
#       The algorithm core. Include dir <pkg>/include. It may depend on Eigen,
#       PCL, FLANN, OpenCV, yaml-cpp, fmt, other cores and tinyline::common
#       (linked to every core and node library), never on the bus or the
#       messages: configure fails if it tries (the layering rule).
#   tinyline_node_library(<name> SOURCES ... [DEPS ...] [NOT_INSTALLED])
#       Thin nodes. Adds tinyline::bus and tinyline::msgs. Include dir <pkg>/nodes/include.
#       NOT_INSTALLED: for the build tree only (nodes on evaluation libraries).
#   tinyline_sim_library(<name> SOURCES ... [DEPS ...] [PRIVATE_DEPS ...])
#       A package's room for simulation (<pkg>/sim/): its simulated nodes and
#       devices, on the simulator. Include dir <pkg>/sim/include. Not a core or
#       node library (the layering tests let it link sim) and not installed.
#   tinyline_test(<name> SOURCES ... [LIBS ...] [LABELS ...])
#       A GoogleTest executable; each TEST() becomes a ctest entry.
#
# Targets are named tinyline_<name> with an alias tinyline::<name>, and are
# exported so a downstream project can find_package(tinyline).

set(_TL_FORBIDDEN_IN_CORE tinyline::bus tinyline::msgs tinyline_bus tinyline_msgs)

# Every core and node library, for the layering tests (test/layering).
function(tinyline_layered_library target)
  set_property(GLOBAL APPEND PROPERTY TINYLINE_LAYERED_LIBRARIES ${target})
endfunction()

function(_tinyline_export target name)
  add_library(tinyline::${name} ALIAS ${target})
  set_target_properties(${target} PROPERTIES EXPORT_NAME ${name})
  install(TARGETS ${target} EXPORT tinylineTargets
    ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
    LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
    RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR}
    INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
endfunction()

function(tinyline_core_library name)
  cmake_parse_arguments(ARG "" "" "SOURCES;DEPS;PRIVATE_DEPS" ${ARGN})
  foreach(dep IN LISTS ARG_DEPS ARG_PRIVATE_DEPS)
    if(dep IN_LIST _TL_FORBIDDEN_IN_CORE)
      message(FATAL_ERROR "core library '${name}' may not depend on '${dep}': cores never see the bus or messages (docs/developing.md)")
    endif()
  endforeach()
  set(target tinyline_${name})
  add_library(${target} STATIC ${ARG_SOURCES})
  target_include_directories(${target} PUBLIC
    $<BUILD_INTERFACE:${CMAKE_CURRENT_SOURCE_DIR}/include>
    $<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}>)
  target_link_libraries(${target} PUBLIC ${ARG_DEPS} tinyline::common PRIVATE ${ARG_PRIVATE_DEPS})
  tinyline_apply_flags(${target})
  _tinyline_export(${target} ${name})
  tinyline_layered_library(${target})
  if(EXISTS ${CMAKE_CURRENT_SOURCE_DIR}/include)
    install(DIRECTORY ${CMAKE_CURRENT_SOURCE_DIR}/include/ DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
  endif()
endfunction()

function(tinyline_node_library name)
  cmake_parse_arguments(ARG "NOT_INSTALLED" "" "SOURCES;DEPS;PRIVATE_DEPS" ${ARGN})
  set(target tinyline_${name})
  add_library(${target} STATIC ${ARG_SOURCES})
  target_include_directories(${target} PUBLIC
    $<BUILD_INTERFACE:${CMAKE_CURRENT_SOURCE_DIR}/nodes/include>
    $<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}>)
  target_link_libraries(${target} PUBLIC ${ARG_DEPS} tinyline::bus tinyline::msgs tinyline::common PRIVATE ${ARG_PRIVATE_DEPS})
  tinyline_apply_flags(${target})
  tinyline_layered_library(${target})
  if(ARG_NOT_INSTALLED)
    # For nodes built on libraries that are not installed (evaluation code):
    # the build tree's tools and tests use them, a downstream project cannot.
    add_library(tinyline::${name} ALIAS ${target})
    return()
  endif()
  _tinyline_export(${target} ${name})
  if(EXISTS ${CMAKE_CURRENT_SOURCE_DIR}/nodes/include)
    install(DIRECTORY ${CMAKE_CURRENT_SOURCE_DIR}/nodes/include/ DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
  endif()
endfunction()

function(tinyline_sim_library name)
  cmake_parse_arguments(ARG "" "" "SOURCES;DEPS;PRIVATE_DEPS" ${ARGN})
  set(target tinyline_${name})
  add_library(${target} STATIC ${ARG_SOURCES})
  add_library(tinyline::${name} ALIAS ${target})
  target_include_directories(${target} PUBLIC ${CMAKE_CURRENT_SOURCE_DIR}/sim/include)
  target_link_libraries(${target} PUBLIC ${ARG_DEPS} tinyline::sim_core tinyline::common PRIVATE ${ARG_PRIVATE_DEPS})
  tinyline_apply_flags(${target})
endfunction()

function(tinyline_test name)
  if(NOT TINYLINE_BUILD_TESTS)
    return()
  endif()
  cmake_parse_arguments(ARG "" "TIMEOUT;LAUNCHER" "SOURCES;LIBS;LABELS" ${ARGN})
  add_executable(${name} ${ARG_SOURCES})
  if(ARG_LAUNCHER)
    # Runs the binary through a script (listing and every test), e.g. in a
    # network namespace of its own.
    set_target_properties(${name} PROPERTIES CROSSCOMPILING_EMULATOR ${ARG_LAUNCHER})
  endif()
  target_link_libraries(${name} PRIVATE ${ARG_LIBS} GTest::gtest GTest::gmock GTest::gtest_main)
  target_compile_definitions(${name} PRIVATE
    TINYLINE_SOURCE_DIR="${PROJECT_SOURCE_DIR}"
    TINYLINE_BINARY_DIR="${PROJECT_BINARY_DIR}"
    TINYLINE_VENV_PYTHON="${TINYLINE_VENV_PYTHON}")
  tinyline_apply_flags(${name})
  if(NOT ARG_TIMEOUT)
    set(ARG_TIMEOUT 300)
  endif()
  gtest_discover_tests(${name}
    DISCOVERY_MODE PRE_TEST
    PROPERTIES TIMEOUT ${ARG_TIMEOUT} LABELS "${ARG_LABELS}"
    WORKING_DIRECTORY ${CMAKE_CURRENT_BINARY_DIR})
endfunction()

# A package whose exported targets need a third-party package downstream
# records the find_dependency() line here; it lands in tinylineConfig.cmake.
function(tinyline_export_dependency line)
  set_property(GLOBAL APPEND PROPERTY TINYLINE_EXPORT_DEPENDENCIES "${line}")
endfunction()

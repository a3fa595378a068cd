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
  # One export set per library: find_package(tinyline COMPONENTS <name>)
  # loads it and only what it links (tinyline_install_components below).
  set_property(GLOBAL APPEND PROPERTY TINYLINE_EXPORTED_TARGETS ${target})
  install(TARGETS ${target} EXPORT tinyline_${name}Targets
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
# records its find_dependency() line here (with the version and components it
# needs); a component that links one of that package's targets gets the line.
function(tinyline_export_dependency line)
  string(REGEX MATCH "^find_dependency\\(([A-Za-z0-9_-]+)" _m "${line}")
  if(NOT _m)
    message(FATAL_ERROR "tinyline_export_dependency: expected 'find_dependency(<Package> ...)', got '${line}'")
  endif()
  get_property(_have GLOBAL PROPERTY TINYLINE_FIND_LINE_${CMAKE_MATCH_1} SET)
  if(NOT _have)
    set_property(GLOBAL PROPERTY TINYLINE_FIND_LINE_${CMAKE_MATCH_1} "${line}")
  endif()
endfunction()
tinyline_export_dependency("find_dependency(Threads)")
tinyline_export_dependency("find_dependency(Eigen3 3.4 NO_MODULE)")
tinyline_export_dependency("find_dependency(yaml-cpp)")
tinyline_export_dependency("find_dependency(fmt)")
tinyline_export_dependency("find_dependency(CLI11)")
tinyline_export_dependency("find_dependency(jsoncpp CONFIG)")

# The package that defines a third-party target a tinyline library links, by
# the target's name. A target missing here stops configure: its component
# would not find it downstream.
set(_TL_THIRD_PARTY_PATTERNS
    "^Threads::=Threads" "^Eigen3::=Eigen3" "^fmt::=fmt" "^yaml-cpp=yaml-cpp" "^CycloneDDS::=CycloneDDS"
    "^pcl_=PCL" "^FLANN::=PCL" "^Boost::=PCL" "^VTK::=PCL" "^QHULL::=PCL" "^opencv_=OpenCV"
    "^CLI11::=CLI11" "^JsonCpp::=jsoncpp")

function(_tinyline_third_party_package item out)
  set(${out} "" PARENT_SCOPE)
  foreach(pair IN LISTS _TL_THIRD_PARTY_PATTERNS)
    string(REPLACE "=" ";" pair "${pair}")
    list(GET pair 0 _re)
    list(GET pair 1 _pkg)
    if(item MATCHES "${_re}")
      set(${out} ${_pkg} PARENT_SCOPE)
      return()
    endif()
  endforeach()
  if(ARGN STREQUAL "OPTIONAL")
    return()
  endif()
  message(FATAL_ERROR "tinyline: an installed library links '${item}'; add the package that defines it to "
                      "_TL_THIRD_PARTY_PATTERNS in cmake/TinylinePackage.cmake")
endfunction()

# What `target` needs downstream: the tinyline components (export names) and
# the third-party packages. A static library's private links count: they
# land in its interface as $<LINK_ONLY:...>.
function(_tinyline_component_needs target out_components out_packages)
  get_target_property(_type ${target} TYPE)
  get_target_property(_items ${target} INTERFACE_LINK_LIBRARIES)
  if(NOT _type STREQUAL "INTERFACE_LIBRARY")
    get_target_property(_private ${target} LINK_LIBRARIES)
    list(APPEND _items ${_private})
  endif()
  set(_components "")
  set(_packages "")
  foreach(item IN LISTS _items)
    string(REGEX REPLACE "^\\$<LINK_ONLY:(.*)>$" "\\1" item "${item}")
    if(NOT item OR item MATCHES "-NOTFOUND$" OR item MATCHES "^\\$<" OR item MATCHES "^-" OR IS_ABSOLUTE "${item}")
      continue()  # flags and full paths need no find; generator expressions are not used here
    endif()
    if(NOT TARGET ${item})
      # A third-party target imported in a package's folder is not visible
      # here: known by its name; anything else is a system library (dl, m).
      _tinyline_third_party_package(${item} _pkg OPTIONAL)
      if(_pkg)
        list(APPEND _packages ${_pkg})
      elseif(item MATCHES "::")
        _tinyline_third_party_package(${item} _pkg)
      endif()
      continue()
    endif()
    get_target_property(_real ${item} ALIASED_TARGET)
    if(NOT _real)
      set(_real ${item})
    endif()
    get_property(_exported GLOBAL PROPERTY TINYLINE_EXPORTED_TARGETS)
    if(_real IN_LIST _exported)
      get_target_property(_name ${_real} EXPORT_NAME)
      list(APPEND _components ${_name})
    else()
      _tinyline_third_party_package(${item} _pkg)
      list(APPEND _packages ${_pkg})
    endif()
  endforeach()
  list(REMOVE_DUPLICATES _components)
  list(REMOVE_DUPLICATES _packages)
  set(${out_components} "${_components}" PARENT_SCOPE)
  set(${out_packages} "${_packages}" PARENT_SCOPE)
endfunction()

# One component file per exported library: the components it links first,
# then find_dependency() of its third-party packages, then its targets.
function(_tinyline_write_component target dir out_file)
  get_target_property(_name ${target} EXPORT_NAME)
  _tinyline_component_needs(${target} _components _packages)
  set(_text "# Generated by cmake/TinylinePackage.cmake: component ${_name} and what it links.\n")
  string(APPEND _text "include_guard(GLOBAL)\n")
  foreach(c IN LISTS _components)
    string(APPEND _text "include(\"\${CMAKE_CURRENT_LIST_DIR}/tinyline_${c}-component.cmake\")\n")
  endforeach()
  string(APPEND _text "if(DEFINED tinyline_FOUND AND NOT tinyline_FOUND)\n  return()\nendif()\n")
  foreach(p IN LISTS _packages)
    get_property(_line GLOBAL PROPERTY TINYLINE_FIND_LINE_${p})
    string(APPEND _text "${_line}\n")
  endforeach()
  string(APPEND _text "include(\"\${CMAKE_CURRENT_LIST_DIR}/tinyline_${_name}Targets.cmake\")\n")
  set(_file ${dir}/tinyline_${_name}-component.cmake)
  file(WRITE ${_file} "${_text}")
  set(${out_file} ${_file} PARENT_SCOPE)
  set(TINYLINE_COMPONENT_NAMES ${TINYLINE_COMPONENT_NAMES} ${_name} PARENT_SCOPE)
endfunction()

# `cmake --install --strip` strips executables but leaves static libraries
# whole (CMake keeps their symbol tables); their debug information is most of
# an install's size, so --strip drops it too (symbols stay: they still link).
function(_tinyline_strip_installed_archive target)
  get_target_property(_type ${target} TYPE)
  if(NOT _type STREQUAL "STATIC_LIBRARY" OR NOT CMAKE_STRIP)
    return()
  endif()
  install(CODE "if(CMAKE_INSTALL_DO_STRIP)
  execute_process(COMMAND \"${CMAKE_STRIP}\" --strip-debug
    \"\$ENV{DESTDIR}\${CMAKE_INSTALL_PREFIX}/${CMAKE_INSTALL_LIBDIR}/$<TARGET_FILE_NAME:${target}>\"
    COMMAND_ERROR_IS_FATAL ANY)
endif()")
endfunction()

# Called once at the end of the top-level CMakeLists, when every target is
# known: installs each export set, its component file and tinylineConfig.cmake.
function(tinyline_install_components)
  set(_dest ${CMAKE_INSTALL_LIBDIR}/cmake/tinyline)
  set(_dir ${PROJECT_BINARY_DIR}/tinyline-components)
  file(REMOVE_RECURSE ${_dir})
  get_property(_targets GLOBAL PROPERTY TINYLINE_EXPORTED_TARGETS)
  set(TINYLINE_COMPONENT_NAMES "")
  foreach(target IN LISTS _targets)
    _tinyline_write_component(${target} ${_dir} _file)
    get_target_property(_name ${target} EXPORT_NAME)
    install(EXPORT tinyline_${_name}Targets NAMESPACE tinyline:: DESTINATION ${_dest}
            FILE tinyline_${_name}Targets.cmake)
    install(FILES ${_file} DESTINATION ${_dest})
    _tinyline_strip_installed_archive(${target})
  endforeach()
  configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/tinylineConfig.cmake.in
    ${PROJECT_BINARY_DIR}/tinylineConfig.cmake INSTALL_DESTINATION ${_dest})
  write_basic_package_version_file(${PROJECT_BINARY_DIR}/tinylineConfigVersion.cmake
    COMPATIBILITY SameMinorVersion)
  install(FILES ${PROJECT_BINARY_DIR}/tinylineConfig.cmake ${PROJECT_BINARY_DIR}/tinylineConfigVersion.cmake
          DESTINATION ${_dest})
endfunction()

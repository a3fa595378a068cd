# SPDX-License-Identifier: Apache-2.0
# Included (CMAKE_PROJECT_INCLUDE) when a ROS 2 package is built against the
# registry's Jazzy wheels instead of a ROS 2 install: the message packages'
# exported Python targets name the include folders of the machine that built
# the wheels (/opt/python/...); at the end of the configure step they are
# pointed at this machine's Python and NumPy headers. A real ROS 2 install
# needs none of this.
function(_tinyline_fix_wheel_targets)
  find_package(Python3 REQUIRED COMPONENTS Interpreter Development NumPy)
  get_directory_property(_targets IMPORTED_TARGETS)
  foreach(_t ${_targets})
    get_target_property(_inc ${_t} INTERFACE_INCLUDE_DIRECTORIES)
    if(_inc AND _inc MATCHES "/opt/python/")
      list(TRANSFORM _inc REPLACE "^/opt/python/.*/numpy/_core/include$" "${Python3_NumPy_INCLUDE_DIRS}")
      list(TRANSFORM _inc REPLACE "^/opt/python/[^;]*/include/python3[.0-9]*$" "${Python3_INCLUDE_DIRS}")
      set_target_properties(${_t} PROPERTIES INTERFACE_INCLUDE_DIRECTORIES "${_inc}")
    endif()
  endforeach()
endfunction()
cmake_language(DEFER CALL _tinyline_fix_wheel_targets)

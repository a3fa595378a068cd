# SPDX-License-Identifier: Apache-2.0
# docs/parameters.md is `tinyline describe --all --markdown`: fails, with the
# command that brings it up to date, when a table changed and the doc did not.
execute_process(COMMAND ${TINYLINE} describe --all --markdown OUTPUT_FILE ${OUT} RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "tinyline describe --all --markdown failed (${rc})")
endif()
file(READ ${OUT} made)
file(READ ${DOC} doc)
if(NOT made STREQUAL doc)
  message(FATAL_ERROR "docs/parameters.md is out of date with the nodes' parameter tables; regenerate it:\n"
                      "  ${TINYLINE} describe --all --markdown > docs/parameters.md")
endif()

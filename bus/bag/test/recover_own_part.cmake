# SPDX-License-Identifier: Apache-2.0
# `tinyline bag recover FILE.part FILE` (the repair docs/bags.md gives for a
# killed recording) used to take its own input for its temporary, truncate
# it and remove it: the recording was gone. It must refuse, leaving FILE.part
# byte for byte. And `bag recover other.mcap FILE` must not replace a leftover
# FILE.part. Arguments: -DTL=tinyline -DCUT=a cut bag -DDIR=scratch folder.
file(REMOVE_RECURSE ${DIR})
file(MAKE_DIRECTORY ${DIR})
configure_file(${CUT} ${DIR}/rec.mcap.part COPYONLY)
file(SHA256 ${DIR}/rec.mcap.part before)
foreach(in ${DIR}/rec.mcap.part ${CUT})
  execute_process(COMMAND ${TL} bag recover ${in} ${DIR}/rec.mcap RESULT_VARIABLE rc OUTPUT_VARIABLE out
                  ERROR_VARIABLE err)
  message("${out}${err}")
  if(rc EQUAL 0)
    message(FATAL_ERROR "bag recover ${in} rec.mcap exited 0 over a leftover rec.mcap.part")
  endif()
  if(NOT "${out}${err}" MATCHES "rec.mcap.part (is an input of this command|exists)")
    message(FATAL_ERROR "the refusal does not name rec.mcap.part")
  endif()
  if(NOT EXISTS ${DIR}/rec.mcap.part)
    message(FATAL_ERROR "the recording rec.mcap.part is gone")
  endif()
  file(SHA256 ${DIR}/rec.mcap.part after)
  if(NOT before STREQUAL after)
    message(FATAL_ERROR "the recording rec.mcap.part was changed")
  endif()
  if(EXISTS ${DIR}/rec.mcap)
    message(FATAL_ERROR "rec.mcap was written from a refused run")
  endif()
endforeach()

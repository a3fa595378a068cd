# One place for compiler flags (STYLE.md habit 11): every project target calls
# tinyline_apply_flags(), which adds the warning set, warnings-as-errors and
# the sanitizer chosen with -DTINYLINE_SANITIZE=...

set(TINYLINE_WARNINGS -Wall -Wextra -Wpedantic -Werror)

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

# Warnings for lodestone's own targets only (never for generated or third-party code).
function(lode_set_warnings target)
  target_compile_options(${target} PRIVATE -Wall -Wextra -Wpedantic -Wshadow -Wnon-virtual-dtor
    -Wold-style-cast -Wcast-align -Woverloaded-virtual -Wnull-dereference -Wimplicit-fallthrough)
  if(LODE_WERROR)
    target_compile_options(${target} PRIVATE -Werror)
  endif()
endfunction()

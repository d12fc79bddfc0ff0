# -DLODE_SANITIZE=address;undefined builds everything with those sanitizers.
if(LODE_SANITIZE)
  foreach(s IN LISTS LODE_SANITIZE)
    add_compile_options(-fsanitize=${s} -fno-omit-frame-pointer)
    add_link_options(-fsanitize=${s})
  endforeach()
  message(STATUS "lodestone: sanitizers ${LODE_SANITIZE}")
endif()

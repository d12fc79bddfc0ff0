# -DLODE_SANITIZE=address;undefined builds everything with those sanitizers.
if(LODE_SANITIZE)
  foreach(s IN LISTS LODE_SANITIZE)
    add_compile_options(-fsanitize=${s} -fno-omit-frame-pointer)
    add_link_options(-fsanitize=${s})
  endforeach()
  if("thread" IN_LIST LODE_SANITIZE)
    # g++ refuses std::atomic_thread_fence under TSan (-Wtsan). The only fences order a board's
    # memory-mapped registers (io.vme_pentek) against the device or its emulator, another
    # process: nothing ThreadSanitizer could check anyway.
    add_compile_options(-Wno-tsan)
  endif()
  message(STATUS "lodestone: sanitizers ${LODE_SANITIZE}")
endif()

# lode_add_fuzz_test(NAME <ctest name> TARGET <fuzzer> SOURCES <files...> [INCLUDES <dirs...>]
#                    [DEPENDS <headers...>] [LINK <args...>] [TARGETS <targets...>]
#                    [ENVIRONMENT <VAR=value...>] CORPUS <seed dir> RUNS <n> MAX_LEN <bytes>)
#
# libFuzzer with AddressSanitizer and UBSan over our sources (the CAN frame decoder, the VME
# register-map parser, the configuration loader, the command parsers): a fixed budget of runs
# from a seed corpus, seed 1, as a ctest. LINK adds libraries (and generator expressions such
# as $<TARGET_FILE:...>) built without sanitizers; TARGETS are built first. Built with clang++ directly, since the project
# compiles with g++. Without clang++ (setup.sh installs it) the test is a stand-in that fails
# (or skips, with LODE_REQUIRE_TEST_TOOLS=OFF) naming what to install.
find_program(LODE_CLANGXX NAMES clang++-14 clang++)

function(lode_add_fuzz_test)
  cmake_parse_arguments(F "" "NAME;TARGET;CORPUS;RUNS;MAX_LEN" "SOURCES;INCLUDES;DEPENDS;LINK;TARGETS;ENVIRONMENT" ${ARGN})
  if(NOT LODE_BUILD_TESTS)
    return()
  endif()
  # A fuzzer that links the project's libraries (LINK) is an ASan process: it cannot load
  # libraries built with another sanitizer (ThreadSanitizer's run-time refuses to share one).
  # The fuzzers belong to the plain and the ASan builds; a TSan build has nothing to add.
  if(F_LINK AND "thread" IN_LIST LODE_SANITIZE)
    return()
  endif()
  if(NOT LODE_CLANGXX)
    lode_add_unavailable_test(NAME ${F_NAME}
      WHY "clang++ not found (apt-get install clang libclang-rt-14-dev): libFuzzer cannot build ${F_TARGET}")
    return()
  endif()
  set(fuzzer ${CMAKE_CURRENT_BINARY_DIR}/${F_TARGET})
  list(TRANSFORM F_INCLUDES PREPEND -I)
  add_custom_command(OUTPUT ${fuzzer}
    COMMAND ${LODE_CLANGXX} -std=c++20 -O1 -g -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=all
            ${F_INCLUDES} -I${PROJECT_SOURCE_DIR}/core/include ${F_SOURCES} ${F_LINK} -o ${fuzzer}
    DEPENDS ${F_SOURCES} ${F_DEPENDS} ${F_TARGETS}
    COMMENT "libFuzzer target ${F_TARGET} (clang)")
  add_custom_target(lode_${F_TARGET} ALL DEPENDS ${fuzzer})
  # A copy of the seed corpus: libFuzzer adds what it finds to the first corpus directory.
  add_test(NAME ${F_NAME}
    COMMAND sh -c "rm -rf corpus_${F_TARGET} && cp -r ${F_CORPUS} corpus_${F_TARGET} && \
                   ${fuzzer} -runs=${F_RUNS} -seed=1 -max_len=${F_MAX_LEN} corpus_${F_TARGET}"
    WORKING_DIRECTORY ${CMAKE_CURRENT_BINARY_DIR})
  set_tests_properties(${F_NAME} PROPERTIES TIMEOUT 300 ENVIRONMENT "${F_ENVIRONMENT}")
endfunction()

# Fuzz targets: one way to declare them, for every module (core/*/fuzz, server/fuzz).
#
#   tinstream_add_fuzzer(NAME SOURCES src... DEPS target... CORPUS dir... [MAX_LEN bytes]
#                        [TIMEOUT seconds] [DICT file] [REGRESSIONS dir])
#
# A fuzz target defines extern "C" int LLVMFuzzerTestOneInput(const uint8_t*, size_t) and aborts
# on a broken property. Each fuzz folder holds CMakeLists.txt calling this, its sources, its seed
# corpus and regressions/ (inputs that once crashed it; scripts/fuzz.sh tells where to put them;
# REGRESSIONS names another folder, for a target whose sources live in another module's folder).
#
# - TINSTREAM_FUZZ=ON (a clang build, scripts/fuzz.sh makes one in build-fuzz): NAME is a libFuzzer
#   binary (bin/NAME) with ASan + UBSan, every library instrumented for coverage
#   (-fsanitize=fuzzer-no-link globally), and a line in ${CMAKE_BINARY_DIR}/fuzzers.tsv
#   (name, binary, max_len, timeout, dict, corpus dirs) that scripts/fuzz.sh runs.
# - In every build with tests (any compiler, the sanitizer builds included): NAME_replay runs
#   the target once on every file of its corpus and regressions/, as the CTest test
#   Fuzz.NAME.Replay; so every crash a fuzzer ever found stays a regression test.
# The fuzz folders are added by the top-level CMakeLists.txt (tinstream_add_fuzz_folders).

option(TINSTREAM_FUZZ "Build the libFuzzer targets (clang only; scripts/fuzz.sh)" OFF)

function(tinstream_setup_fuzzing)
  if(NOT TINSTREAM_FUZZ)
    return()
  endif()
  if(NOT CMAKE_CXX_COMPILER_ID MATCHES Clang)
    message(FATAL_ERROR "TINSTREAM_FUZZ needs clang (-DCMAKE_CXX_COMPILER=clang++)")
  endif()
  if(TINSTREAM_ASAN OR TINSTREAM_TSAN)
    message(FATAL_ERROR "TINSTREAM_FUZZ brings its own sanitizers; leave TINSTREAM_ASAN/TSAN off")
  endif()
  add_compile_options(-fsanitize=fuzzer-no-link,address,undefined -fno-sanitize-recover=undefined
                      -fno-omit-frame-pointer)
  add_link_options(-fsanitize=address,undefined)
  file(WRITE ${CMAKE_BINARY_DIR}/fuzzers.tsv "")
  add_custom_target(fuzzers)
endfunction()

# tinstream_fuzz_without_cmp_trace(target [SOURCES file...])
# Compiles a target of a fuzz build (or only the given sources of it, from the folder that
# declares the target) without -fsanitize-coverage=trace-cmp: no callback on each of its integer
# comparisons. Those callbacks only feed the mutator's hints (libFuzzer's table of
# compared values, and value-profile features, which scripts/fuzz.sh does not turn on); edge
# coverage, what decides which inputs are kept, is unchanged. For libraries whose comparisons are
# on computed state (indices, counts), never on input bytes, where the callbacks cost a large share
# of each execution and guide nothing: docs/SECURITY.md, "Why laz_fuzzer and kernel_fuzzer were
# slow". A no-op in other builds.
function(tinstream_fuzz_without_cmp_trace target)
  cmake_parse_arguments(ARG "" "" "SOURCES" ${ARGN})
  if(NOT TINSTREAM_FUZZ)
    return()
  endif()
  if(ARG_SOURCES)
    set_source_files_properties(${ARG_SOURCES} TARGET_DIRECTORY ${target}
                                PROPERTIES COMPILE_OPTIONS -fno-sanitize-coverage=trace-cmp)
  else()
    target_compile_options(${target} PRIVATE -fno-sanitize-coverage=trace-cmp)
  endif()
endfunction()

function(tinstream_add_fuzzer name)
  cmake_parse_arguments(ARG "" "MAX_LEN;TIMEOUT;DICT;REGRESSIONS" "SOURCES;DEPS;CORPUS" ${ARGN})
  if(NOT ARG_MAX_LEN)
    set(ARG_MAX_LEN 65536)
  endif()
  if(NOT ARG_TIMEOUT)
    set(ARG_TIMEOUT 10)
  endif()
  if(NOT ARG_DICT)
    set(ARG_DICT -)  # fuzzers.tsv has no empty fields (tabs are whitespace to `read`)
  endif()
  set(regressions ${CMAKE_CURRENT_SOURCE_DIR}/regressions)
  if(ARG_REGRESSIONS)
    set(regressions ${ARG_REGRESSIONS})
  endif()
  if(TINSTREAM_FUZZ)
    add_executable(${name} ${ARG_SOURCES})
    target_link_libraries(${name} PRIVATE ${ARG_DEPS})
    target_link_options(${name} PRIVATE -fsanitize=fuzzer)
    tinstream_configure_target(${name})
    add_dependencies(fuzzers ${name})
    list(JOIN ARG_CORPUS "\t" corpus)
    file(APPEND ${CMAKE_BINARY_DIR}/fuzzers.tsv
         "${name}\t${CMAKE_RUNTIME_OUTPUT_DIRECTORY}/${name}\t${ARG_MAX_LEN}\t${ARG_TIMEOUT}\t${ARG_DICT}\t${regressions}\t${corpus}\n")
  endif()
  if(TINSTREAM_BUILD_TESTS)
    add_executable(${name}_replay ${ARG_SOURCES} ${PROJECT_SOURCE_DIR}/core/base/fuzz/replay_main.cpp)
    target_link_libraries(${name}_replay PRIVATE ${ARG_DEPS})
    tinstream_configure_target(${name}_replay)
    add_test(NAME Fuzz.${name}.Replay COMMAND ${name}_replay ${ARG_CORPUS} ${regressions})
    set_tests_properties(Fuzz.${name}.Replay PROPERTIES TIMEOUT 600)
  endif()
endfunction()

# Adds every fuzz folder (core/*/fuzz, server/fuzz) that has a CMakeLists.txt and whose module's
# targets exist in this build.
function(tinstream_add_fuzz_folders)
  if(NOT TINSTREAM_FUZZ AND NOT TINSTREAM_BUILD_TESTS)
    return()
  endif()
  file(GLOB folders LIST_DIRECTORIES true CONFIGURE_DEPENDS
       ${PROJECT_SOURCE_DIR}/core/*/fuzz ${PROJECT_SOURCE_DIR}/server/fuzz)
  foreach(folder IN LISTS folders)
    get_filename_component(module_dir ${folder} DIRECTORY)
    get_filename_component(module ${module_dir} NAME)
    if(module STREQUAL "server")
      set(target tinstream_server)
    else()
      set(target tinstream_${module})
    endif()
    if(EXISTS ${folder}/CMakeLists.txt AND TARGET ${target})
      add_subdirectory(${folder} ${CMAKE_BINARY_DIR}/fuzz/${module})
    endif()
  endforeach()
endfunction()

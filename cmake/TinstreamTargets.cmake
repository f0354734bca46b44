# One place that says how every tinstream target is compiled.
#
#   tinstream_setup_toolchain()            ccache, sanitizers (global, so gtest and libs agree)
#   tinstream_configure_target(t)          C++20, warnings, warnings-as-errors
#   tinstream_add_library(NAME module SOURCES ... [PUBLIC_DEPS ...] [PRIVATE_DEPS ...])
#       builds target tinstream_<module> (alias tinstream::<module>) with include/ as its public
#       surface and src/ private.
#   tinstream_add_test(NAME name SOURCES ... DEPS ... [OPTIMIZED_SOURCES ...])
#       a GoogleTest executable registered with CTest (one CTest entry per TEST()). Test code is
#       built for compile speed (see below); OPTIMIZED_SOURCES are test files that do heavy work
#       of their own (CGAL references) and keep the tree's optimisation.

function(tinstream_setup_toolchain)
  find_program(CCACHE_PROGRAM ccache)
  if(CCACHE_PROGRAM AND NOT CMAKE_CXX_COMPILER_LAUNCHER)
    set(CMAKE_CXX_COMPILER_LAUNCHER ${CCACHE_PROGRAM} PARENT_SCOPE)
    set(CMAKE_C_COMPILER_LAUNCHER ${CCACHE_PROGRAM} PARENT_SCOPE)
  endif()
  if(NOT CMAKE_BUILD_TYPE AND NOT CMAKE_CONFIGURATION_TYPES)
    set(CMAKE_BUILD_TYPE RelWithDebInfo CACHE STRING "Build type" FORCE)
  endif()
  if(TINSTREAM_ASAN AND TINSTREAM_TSAN)
    message(FATAL_ERROR "TINSTREAM_ASAN and TINSTREAM_TSAN cannot be combined")
  endif()
  if(TINSTREAM_ASAN)
    add_compile_options(-fsanitize=address,undefined -fno-omit-frame-pointer -fno-sanitize-recover=undefined)
    add_link_options(-fsanitize=address,undefined)
  endif()
  if(TINSTREAM_TSAN)
    add_compile_options(-fsanitize=thread -fno-omit-frame-pointer)
    add_link_options(-fsanitize=thread)
    # GCC 12 warns (-Wtsan) wherever Boost.Asio's std_fenced_block uses atomic_thread_fence
    # (TSan does not model fences): a warning, not an error, in every TSan target (the server's
    # stop() and TLS handlers reach it since 3e2b1dd). TSan still reports any race it sees.
    if(CMAKE_CXX_COMPILER_ID STREQUAL "GNU")
      add_compile_options(-Wno-error=tsan)
    endif()
  endif()
  # lld when installed (scripts/install-deps.sh installs it): several times faster than GNU ld
  # on the test executables (tens of MB with debug info, 31 of them per tree in CI).
  option(TINSTREAM_LLD "Link with lld when it is installed" ON)
  find_program(TINSTREAM_LD_LLD ld.lld)
  if(TINSTREAM_LLD AND TINSTREAM_LD_LLD)
    add_link_options(-fuse-ld=lld)
  endif()
  set(CMAKE_EXPORT_COMPILE_COMMANDS ON PARENT_SCOPE)
  # Unity builds of the test executables (CMake's UNITY_BUILD: TINSTREAM_UNITY_BATCH .cpp files
  # #included into one generated file and compiled as one, so gtest and the shared headers are
  # parsed once a batch): CI's compile CPU (docs/SECURITY.md, "CI"). The product (libraries and
  # executables) is compiled one object per file unless TINSTREAM_UNITY_PRODUCT. OFF for
  # development: an edit recompiles its whole batch.
  option(TINSTREAM_UNITY "Unity-build the test executables" OFF)
  set(TINSTREAM_UNITY_BATCH 8 CACHE STRING "Source files per unity batch")
  # The product too (every target created after this: libraries, executables), for a tree that
  # is only tested (the ASan tree): what ships stays one object per file.
  option(TINSTREAM_UNITY_PRODUCT "Unity-build the libraries and executables too" OFF)
  if(TINSTREAM_UNITY_PRODUCT)
    set(CMAKE_UNITY_BUILD ON PARENT_SCOPE)
    set(CMAKE_UNITY_BUILD_BATCH_SIZE ${TINSTREAM_UNITY_BATCH} PARENT_SCOPE)
    if(CMAKE_CXX_COMPILER_ID STREQUAL "GNU")
      add_compile_options(-Wno-subobject-linkage)  # see tinstream_unity_warnings
    endif()
  endif()
  option(TINSTREAM_FAST_TEST_BUILD "Compile test code at -O0 (sanitizers) or -O1 (Release)" ON)
  set(TINSTREAM_DISCOVERY_TIMEOUT 120 CACHE STRING
      "Seconds ctest waits for a test executable to list its tests (CMake's default: 5)")
endfunction()

function(tinstream_configure_target target)
  target_compile_features(${target} PUBLIC cxx_std_20)
  set_target_properties(${target} PROPERTIES CXX_EXTENSIONS OFF)
  target_compile_options(${target} PRIVATE -Wall -Wextra -Wpedantic -Wshadow -Wconversion)
  if(TINSTREAM_WERROR)
    target_compile_options(${target} PRIVATE -Werror)
    # GCC 12 at -O3 (Release) reports false -Wrestrict/-Wstringop-overflow on ordinary
    # std::string concatenation inside libstdc++ (GCC bug 105651): warn, don't fail.
    if(CMAKE_CXX_COMPILER_ID STREQUAL "GNU")
      target_compile_options(${target} PRIVATE -Wno-error=restrict -Wno-error=stringop-overflow)
      # With the sanitizers GCC 12 also reports a false -Wmaybe-uninitialized inside Boost.Beast's
      # HTTP parser headers.
      if(TINSTREAM_ASAN OR TINSTREAM_TSAN)
        target_compile_options(${target} PRIVATE -Wno-error=maybe-uninitialized)
      endif()
    endif()
  endif()
endfunction()

# In a unity batch every .cpp is an #included file, and GCC's -Wsubobject-linkage (meant for
# headers) then flags each class of one .cpp holding a member of that file's anonymous namespace.
function(tinstream_unity_warnings target)
  if(CMAKE_CXX_COMPILER_ID STREQUAL "GNU")
    target_compile_options(${target} PRIVATE -Wno-subobject-linkage)
  endif()
endfunction()

# A test executable: unity-built when TINSTREAM_UNITY is on (a source with its own
# COMPILE_OPTIONS, such as OPTIMIZED_SOURCES, stays a file of its own: CMake leaves it out).
function(tinstream_configure_test_target target)
  tinstream_configure_target(${target})
  if(TINSTREAM_UNITY)
    set_target_properties(${target} PROPERTIES UNITY_BUILD ON
                                               UNITY_BUILD_BATCH_SIZE ${TINSTREAM_UNITY_BATCH})
    tinstream_unity_warnings(${target})
  endif()
endfunction()

function(tinstream_add_library module)
  cmake_parse_arguments(ARG "" "" "SOURCES;PUBLIC_DEPS;PRIVATE_DEPS" ${ARGN})
  set(target tinstream_${module})
  add_library(${target} STATIC ${ARG_SOURCES})
  add_library(tinstream::${module} ALIAS ${target})
  target_include_directories(${target}
    PUBLIC $<BUILD_INTERFACE:${CMAKE_CURRENT_SOURCE_DIR}/include>
    PRIVATE ${CMAKE_CURRENT_SOURCE_DIR}/src)
  target_link_libraries(${target} PUBLIC ${ARG_PUBLIC_DEPS} PRIVATE ${ARG_PRIVATE_DEPS})
  tinstream_configure_target(${target})
endfunction()

function(tinstream_add_test name)
  if(NOT TINSTREAM_BUILD_TESTS)
    return()
  endif()
  cmake_parse_arguments(ARG "" "TIMEOUT" "SOURCES;DEPS;OPTIMIZED_SOURCES" ${ARGN})
  add_executable(${name} ${ARG_SOURCES} ${ARG_OPTIMIZED_SOURCES})
  target_link_libraries(${name} PRIVATE ${ARG_DEPS} GTest::gtest GTest::gmock GTest::gtest_main)
  target_compile_definitions(${name} PRIVATE
    TINSTREAM_SHARED_DATA="${TINSTREAM_SHARED_DATA}"
    TINSTREAM_BINARY_DIR="${CMAKE_BINARY_DIR}"
    TINSTREAM_SOURCE_DIR="${PROJECT_SOURCE_DIR}")
  tinstream_configure_test_target(${name})
  # What a test exercises is the libraries, built at the tree's optimisation; the test's own code
  # (gtest macros, Beast clients, CLI11, JSON) is compiled for build speed: -O0 in the sanitizer
  # trees, where instrumenting it at -O1 was half of CI's compile time (integration_test.cpp:
  # 59 s of CPU at -O1 with ASan+UBSan, 22 s at -O0), -O1 in the Release tree. The last -O wins
  # (target options follow CMAKE_CXX_FLAGS_<CONFIG>).
  if(TINSTREAM_FAST_TEST_BUILD)
    if(TINSTREAM_ASAN OR TINSTREAM_TSAN)
      target_compile_options(${name} PRIVATE -O0)
      if(ARG_OPTIMIZED_SOURCES)
        set_source_files_properties(${ARG_OPTIMIZED_SOURCES} TARGET_DIRECTORY ${name}
                                    PROPERTIES COMPILE_OPTIONS -O1)
      endif()
    elseif(CMAKE_BUILD_TYPE STREQUAL "Release")
      target_compile_options(${name} PRIVATE -O1)
    endif()
  endif()
  if(NOT ARG_TIMEOUT)
    set(ARG_TIMEOUT 600)
  endif()
  # Listing the tests takes ~0.05 s, but CI once stalled one listing past CMake's default 5 s
  # (sources_tests, release tree, 2026-11-28: "Process terminated due to timeout", nothing
  # printed) and ctest failed the whole suite for it. A stalled machine is not a failing test.
  gtest_discover_tests(${name} DISCOVERY_MODE PRE_TEST DISCOVERY_TIMEOUT ${TINSTREAM_DISCOVERY_TIMEOUT}
                       PROPERTIES TIMEOUT ${ARG_TIMEOUT})
endfunction()

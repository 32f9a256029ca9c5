# flysfm_add_module(NAME SOURCES ... DEPS ...)
# One static library per module folder, named flysfm_<NAME>. Headers are
# included as "<module>/<file>.h" from the source root.
function(flysfm_add_module name)
  cmake_parse_arguments(ARG "" "" "SOURCES;DEPS" ${ARGN})
  add_library(flysfm_${name} STATIC ${ARG_SOURCES})
  target_include_directories(flysfm_${name} PUBLIC ${PROJECT_SOURCE_DIR})
  target_link_libraries(flysfm_${name} PUBLIC ${ARG_DEPS})
endfunction()

# flysfm_add_module_tests(MODULE DEPS ...)
# Every tests/<module>/<name>_test.cc becomes one executable
# <module>_<name>_test, its Catch2 cases registered with CTest. MODULE may be
# a sub-folder path: "io/formats" gives io_formats_<name>_test. Files named
# *_regression_test.cc read the real data sets: label `regression`, and a
# missing data folder makes them exit 77, which CTest reports as skipped
# (or fail, with FLYSFM_REQUIRE_DATA=1). A file whose stem is in
# FLYSFM_THREADS_TESTS (tests/CMakeLists.txt) also gets the label `threads`.
# Each executable joins the build target of each of its labels
# (<label>_tests), so that a run of one label builds only what it runs.
#
# Every case has a TIMEOUT, so that a hang fails in minutes instead of
# CTest's default 25: FLYSFM_UNIT_TIMEOUT or FLYSFM_REGRESSION_TIMEOUT
# seconds, times FLYSFM_TEST_TIMEOUT_SCALE (tests/CMakeLists.txt: a sanitizer
# build runs several times slower). COST orders a clean run's first `ctest
# -j` (later runs use the times measured): the long regression runs first,
# then the end-to-end ones of FLYSFM_LONG_TESTS, so that the many short
# tests fill the gaps instead of a long one ending the run alone.
function(flysfm_add_module_tests module)
  cmake_parse_arguments(ARG "" "" "DEPS" ${ARGN})
  file(GLOB test_sources CONFIGURE_DEPENDS
       "${CMAKE_CURRENT_SOURCE_DIR}/*_test.cc")
  string(REPLACE "/" "_" target_prefix ${module})
  foreach(source ${test_sources})
    get_filename_component(stem ${source} NAME_WE)
    set(target ${target_prefix}_${stem})
    add_executable(${target} ${source})
    if(stem MATCHES "_regression_test$")
      target_link_libraries(${target} PRIVATE flysfm_test_regression_main
                            ${ARG_DEPS})
      set(label regression)
      set(cost 1000)
      set(timeout ${FLYSFM_REGRESSION_TIMEOUT})
    else()
      target_link_libraries(${target} PRIVATE flysfm_test_main ${ARG_DEPS})
      set(label unit)
      set(cost 1)
      if(stem IN_LIST FLYSFM_LONG_TESTS)
        set(cost 100)
      endif()
      set(timeout ${FLYSFM_UNIT_TIMEOUT})
    endif()
    math(EXPR timeout "${timeout} * ${FLYSFM_TEST_TIMEOUT_SCALE}")
    set(labels ${label})
    if(stem IN_LIST FLYSFM_THREADS_TESTS)
      list(APPEND labels threads)
    endif()
    # --warn NoTests: a case whose name CTest got wrong (a ';' in it splits
    # it) fails instead of passing with nothing run.
    catch_discover_tests(${target}
      TEST_PREFIX "${module}/${stem}: "
      EXTRA_ARGS --warn NoTests
      PROPERTIES SKIP_RETURN_CODE 77 COST ${cost} TIMEOUT ${timeout}
      DISCOVERY_TIMEOUT 30)
    # The labels are set by a CTest include file of our own, read after
    # discovery's (which defines ${target}_TESTS): the PROPERTIES above would
    # split a list of labels into separate properties.
    set(labels_file "${CMAKE_CURRENT_BINARY_DIR}/${target}_labels.cmake")
    file(WRITE "${labels_file}"
      "if(${target}_TESTS)\n"
      "  set_tests_properties(\${${target}_TESTS} PROPERTIES LABELS \"${labels}\")\n"
      "endif()\n")
    set_property(DIRECTORY APPEND PROPERTY TEST_INCLUDE_FILES "${labels_file}")
    foreach(label ${labels})
      add_dependencies(${label}_tests ${target})
    endforeach()
  endforeach()
endfunction()

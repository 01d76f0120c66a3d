# The real-time build: the core's sources compiled a second time with Eigen's run-time
# heap guard (EIGEN_RUNTIME_NO_MALLOC) and assertions live (NDEBUG undefined), and a
# GoogleTest executable, compiled the same way, that runs the servo cycle with Eigen heap
# allocation forbidden (test_no_malloc.cpp). Included at the end of tests/cpp/CMakeLists.txt.

# one list of sources: the virtmech target's own, made absolute
get_target_property(_vm_sources virtmech SOURCES)
get_target_property(_vm_source_dir virtmech SOURCE_DIR)
set(_vm_rt_sources)
foreach(_s IN LISTS _vm_sources)
  if(IS_ABSOLUTE "${_s}" OR _s MATCHES "^\\$<")
    list(APPEND _vm_rt_sources "${_s}")
  else()
    list(APPEND _vm_rt_sources "${_vm_source_dir}/${_s}")
  endif()
endforeach()

add_library(virtmech_no_malloc STATIC
  ${_vm_rt_sources}
  ${CMAKE_CURRENT_LIST_DIR}/no_malloc_build.cpp)
# the same build and usage requirements as virtmech (include directories, Eigen, C++17,
# warnings), copied from the target so that they too are stated once
foreach(_prop INCLUDE_DIRECTORIES LINK_LIBRARIES COMPILE_DEFINITIONS COMPILE_OPTIONS
              COMPILE_FEATURES)
  get_target_property(_own virtmech ${_prop})
  get_target_property(_usage virtmech INTERFACE_${_prop})
  if(_own)
    set_property(TARGET virtmech_no_malloc APPEND PROPERTY ${_prop} "${_own}")
  endif()
  if(_usage)
    set_property(TARGET virtmech_no_malloc APPEND PROPERTY INTERFACE_${_prop} "${_usage}")
  endif()
endforeach()
# PUBLIC: the test executable is compiled the same way
target_compile_definitions(virtmech_no_malloc PUBLIC EIGEN_RUNTIME_NO_MALLOC)
if(MSVC)
  target_compile_options(virtmech_no_malloc PUBLIC /UNDEBUG)
else()
  target_compile_options(virtmech_no_malloc PUBLIC -UNDEBUG)
endif()

add_executable(virtmech_no_malloc_tests ${CMAKE_CURRENT_LIST_DIR}/test_no_malloc.cpp)
target_link_libraries(virtmech_no_malloc_tests PRIVATE virtmech_no_malloc GTest::gtest
                      GTest::gtest_main)
include(GoogleTest)
gtest_discover_tests(virtmech_no_malloc_tests)

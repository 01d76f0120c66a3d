# The C API under AddressSanitizer and UndefinedBehaviorSanitizer: the core's sources
# compiled once more with both, and the C API's tests of out-of-range enumerations
# (test_c_api_enums.cpp) and of the rest of the C API linked against them; any error the
# sanitizers find stops the test. GCC and Clang only. Included by tests/cpp/CMakeLists.txt.
if(NOT CMAKE_CXX_COMPILER_ID MATCHES "GNU|Clang")
  return()
endif()
set(_vm_sanitize -fsanitize=address,undefined -fno-sanitize-recover=all -fno-omit-frame-pointer)

get_target_property(_vm_sources virtmech SOURCES)
get_target_property(_vm_source_dir virtmech SOURCE_DIR)
set(_vm_san_sources)
foreach(_s IN LISTS _vm_sources)
  if(IS_ABSOLUTE "${_s}")
    list(APPEND _vm_san_sources "${_s}")
  else()
    list(APPEND _vm_san_sources "${_vm_source_dir}/${_s}")
  endif()
endforeach()
add_library(virtmech_sanitized STATIC ${_vm_san_sources})
target_include_directories(virtmech_sanitized PUBLIC ${_vm_source_dir}/include)
target_link_libraries(virtmech_sanitized PUBLIC Eigen3::Eigen PRIVATE ${CMAKE_DL_LIBS})
target_compile_features(virtmech_sanitized PUBLIC cxx_std_17)
target_compile_options(virtmech_sanitized PUBLIC ${_vm_sanitize})
target_link_options(virtmech_sanitized PUBLIC ${_vm_sanitize})

add_executable(virtmech_c_api_sanitized_tests
  ${CMAKE_CURRENT_LIST_DIR}/test_c_api_enums.cpp
  ${CMAKE_CURRENT_LIST_DIR}/test_c_api.cpp
  ${CMAKE_CURRENT_LIST_DIR}/test_c_api_shapes.cpp)
target_link_libraries(virtmech_c_api_sanitized_tests PRIVATE virtmech_sanitized GTest::gtest
                      GTest::gtest_main)
include(GoogleTest)
gtest_discover_tests(virtmech_c_api_sanitized_tests TEST_PREFIX "sanitized."
                     PROPERTIES ENVIRONMENT "ASAN_OPTIONS=detect_leaks=1:abort_on_error=1")

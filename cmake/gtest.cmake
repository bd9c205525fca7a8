# GoogleTest: an installed package, else sources (Debian's /usr/src/googletest, or a carried
# copy named by GMM_MCL_GTEST_SRC on machines without it).
find_package(GTest QUIET)
if(NOT TARGET GTest::gtest AND TARGET gtest AND TARGET gtest_main)
  # catkin with testing on built googletest from its sources already (ROS Melodic on Ubuntu
  # 18.04, whose libgtest-dev has no libraries): a second add_subdirectory would clash.
  add_library(GTest::gtest ALIAS gtest)
  add_library(GTest::gtest_main ALIAS gtest_main)
endif()
if(NOT TARGET GTest::gtest)
  set(_gtest_src "")
  foreach(dir ${GMM_MCL_GTEST_SRC} /usr/src/googletest)
    if(EXISTS ${dir}/CMakeLists.txt AND _gtest_src STREQUAL "")
      set(_gtest_src ${dir})
    endif()
  endforeach()
  if(_gtest_src STREQUAL "")
    message(FATAL_ERROR "GoogleTest not found: install libgtest-dev or set GMM_MCL_GTEST_SRC")
  endif()
  set(INSTALL_GTEST OFF CACHE BOOL "" FORCE)
  set(BUILD_GMOCK OFF CACHE BOOL "" FORCE)
  add_subdirectory(${_gtest_src} ${CMAKE_BINARY_DIR}/googletest EXCLUDE_FROM_ALL)
  add_library(GTest::gtest ALIAS gtest)
  add_library(GTest::gtest_main ALIAS gtest_main)
endif()

# gmm_mcl_add_gtest(name source [libraries...]): a gtest suite linked with gtest_main and the
# given libraries, registered with ctest under its name.
function(gmm_mcl_add_gtest name src)
  add_executable(${name} ${src})
  target_link_libraries(${name} PRIVATE ${ARGN} GTest::gtest_main)
  add_test(NAME ${name} COMMAND ${name})
endfunction()

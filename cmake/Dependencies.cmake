# Every dependency comes from Debian 12 packages installed by scripts/setup.sh.
find_package(Threads REQUIRED)
find_package(Eigen3 3.4 REQUIRED NO_MODULE)
find_package(yaml-cpp REQUIRED)
find_package(HDF5 REQUIRED COMPONENTS C)
find_package(GTest REQUIRED)
find_package(OpenMP REQUIRED COMPONENTS CXX)

# LCM 1.3.1 ships no CMake config and its .pc file needs glib; the headers do not.
find_path(LCM_INCLUDE_DIR lcm/lcm-cpp.hpp REQUIRED)
find_library(LCM_LIBRARY lcm REQUIRED)
find_program(LCM_GEN lcm-gen REQUIRED)
add_library(lcm::lcm UNKNOWN IMPORTED)
set_target_properties(lcm::lcm PROPERTIES
  IMPORTED_LOCATION ${LCM_LIBRARY}
  INTERFACE_INCLUDE_DIRECTORIES ${LCM_INCLUDE_DIR})

# HDF5 as one imported target.
add_library(hdf5::c INTERFACE IMPORTED)
set_target_properties(hdf5::c PROPERTIES
  INTERFACE_INCLUDE_DIRECTORIES "${HDF5_C_INCLUDE_DIRS}"
  INTERFACE_LINK_LIBRARIES "${HDF5_C_LIBRARIES}"
  INTERFACE_COMPILE_DEFINITIONS "${HDF5_C_DEFINITIONS}")

# Warnings for the project's own targets.
function(soil_warnings target)
  target_compile_options(${target} PRIVATE -Wall -Wextra -Wno-unused-parameter
    $<$<CXX_COMPILER_ID:GNU>:-Wno-maybe-uninitialized>)
endfunction()

# A GoogleTest executable registered with ctest; tests are discovered one by one.
include(GoogleTest)
function(soil_add_gtest name)
  cmake_parse_arguments(T "" "TIMEOUT" "SOURCES;LIBS;LABELS" ${ARGN})
  add_executable(${name} ${T_SOURCES})
  target_link_libraries(${name} PRIVATE ${T_LIBS} GTest::gtest GTest::gtest_main)
  soil_warnings(${name})
  # Test programs compile at -O1: they are 87 of the C++ files and the heaviest to compile
  # (13-19 s of CPU each at -O3), while the code they measure is in the libraries, built at the
  # build type's level. No -march and no -ffast-math here, so the arithmetic is the same IEEE
  # operations at either level.
  target_compile_options(${name} PRIVATE -O1)
  if(NOT T_TIMEOUT)
    set(T_TIMEOUT 300)
  endif()
  # Idle OpenMP threads sleep (scene.thread_wait's default, which only the DEM programs apply
  # themselves): ctest -j runs two multi-threaded tests at once on two cores, and libgomp's
  # spinning made them take each other's cores (tests slowed 10-500x, timeouts).
  gtest_discover_tests(${name} DISCOVERY_TIMEOUT 60
    PROPERTIES TIMEOUT ${T_TIMEOUT} ENVIRONMENT "OMP_WAIT_POLICY=PASSIVE")
  # The labels are set by a script ctest reads after the discovered tests: a list such as
  # "physics;bus" given in PROPERTIES above reaches set_tests_properties split into words, so
  # the tests had "physics" only (`ctest -L bus` missed them). <name>_TESTS is the list
  # gtest_discover_tests defines for the target.
  if(T_LABELS)
    set(labels_file "${CMAKE_CURRENT_BINARY_DIR}/${name}_labels.cmake")
    file(WRITE "${labels_file}"
      "if(DEFINED ${name}_TESTS)\n  set_tests_properties(\${${name}_TESTS} PROPERTIES LABELS \"${T_LABELS}\")\nendif()\n")
    set_property(DIRECTORY APPEND PROPERTY TEST_INCLUDE_FILES "${labels_file}")
  endif()
endfunction()

# Simbody 3.7 (Debian libsimbody-dev) for the machine models. Debian builds it without
# -DNDEBUG and some SimTKcommon classes change layout under NDEBUG, so every target that
# includes Simbody headers must be compiled without it. Simbody 3.7's headers also fail as
# C++20 (ambiguous reversed operator==): keep them in .cpp files built as C++17.
find_package(Simbody 3.7 CONFIG REQUIRED)
function(soil_simbody_sources target)
  target_link_libraries(${target} PUBLIC SimTKsimbody)
  set_source_files_properties(${ARGN} TARGET_DIRECTORY ${target}
    PROPERTIES COMPILE_OPTIONS "-std=c++17;-UNDEBUG")
endfunction()

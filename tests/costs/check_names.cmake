# cmake -DCTEST=ctest -DBUILD=<build folder> -DNAMES=<a;b;...> -P check_names.cmake
# Fails naming every entry of NAMES that `ctest -N` does not list as a test of BUILD.
execute_process(COMMAND ${CTEST} -N --test-dir ${BUILD} OUTPUT_VARIABLE out RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "ctest -N --test-dir ${BUILD} failed (${rc}):\n${out}")
endif()
set(missing "")
foreach(name IN LISTS NAMES)
  string(FIND "${out}" ": ${name}\n" at)
  if(at EQUAL -1)
    list(APPEND missing "${name}")
  endif()
endforeach()
if(missing)
  message(FATAL_ERROR "tests/costs/CMakeLists.txt names tests that do not exist: ${missing} "
                      "(renamed or removed? update the list)")
endif()
list(LENGTH NAMES n)
message(STATUS "all ${n} tests of tests/costs/CMakeLists.txt exist")

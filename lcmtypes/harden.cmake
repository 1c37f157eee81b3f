# Run after lcm-gen (cmake -P harden.cmake <folder of generated headers>): makes the generated
# C++ decoders refuse counts that the received bytes cannot hold, instead of throwing.
# LCM 1.3.1's decoders take a string's length and an array's count from the datagram and
#  * assign length - 1 characters: a length of 0 or less throws std::length_error;
#  * resize the vector to the count before reading the elements: a negative count throws
#    std::length_error, a large one allocates gigabytes (std::bad_alloc).
# Either escapes from lcm's handle() and ends the process on one forged or damaged datagram
# (found by tests/fuzz/fuzz_messages). Every string takes at least its NUL and every array
# element at least one byte, so a length below 1, a negative count or a count above the bytes
# left is a decoding error (-1), which LCM reports and drops like any other.
file(GLOB headers "${DIR}/cosim/*.hpp")
set(strings 0)
set(arrays 0)
foreach(h ${headers})
  file(READ "${h}" text)
  string(REGEX MATCHALL "_len__ > maxlen - pos\\)" s "${text}")
  string(REGEX REPLACE "if\\(__([A-Za-z0-9_]+)_len__ > maxlen - pos\\) return -1;"
         "if(__\\1_len__ < 1 || __\\1_len__ > maxlen - pos) return -1;" text "${text}")
  string(REGEX MATCHALL "\\.resize\\(this->" a "${text}")
  string(REGEX REPLACE "([ ]*)this->([A-Za-z0-9_]+)\\.resize\\(this->([A-Za-z0-9_]+)\\);"
         "\\1if(this->\\3 < 0 || this->\\3 > maxlen - pos) return -1;\n\\1this->\\2.resize(this->\\3);"
         text "${text}")
  list(LENGTH s ns)
  list(LENGTH a na)
  math(EXPR strings "${strings} + ${ns}")
  math(EXPR arrays "${arrays} + ${na}")
  file(WRITE "${h}" "${text}")
endforeach()
if(strings EQUAL 0 OR arrays EQUAL 0)
  message(FATAL_ERROR "harden.cmake: found ${strings} string and ${arrays} array decoders in "
                      "${DIR}/cosim: lcm-gen's output changed; update lcmtypes/harden.cmake")
endif()

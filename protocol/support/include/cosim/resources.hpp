// What a process uses of the machine, for the timing tables and the benchmarks. Bus-free,
// header-only, Linux (/proc); elsewhere the functions return 0.
#pragma once

#include <cstddef>
#include <fstream>
#include <string>

namespace cosim {

// Peak resident memory of this process so far (VmHWM), in bytes; 0 if unknown.
inline std::size_t peak_resident_bytes() {
  std::ifstream status("/proc/self/status");
  std::string key;
  while (status >> key) {
    if (key == "VmHWM:") {
      std::size_t kb = 0;
      status >> kb;
      return kb * 1024;
    }
    status.ignore(4096, '\n');
  }
  return 0;
}

}  // namespace cosim

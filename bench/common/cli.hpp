// What the bench programs share on their command line (not tests): "--key value" options over
// a table of defaults, and the process's CPU time for the CPU-share column.
#pragma once

#include <ctime>

#include <cstdio>
#include <map>
#include <string>

namespace bench {

// Reads argv[first..] as "--key value" pairs into `opt`, whose keys are the options the program
// knows (with their defaults). An unknown key or a key without a value is refused: false, with
// a message naming it on stderr.
inline bool parse_options(int argc, char** argv, int first, const char* program,
                          std::map<std::string, std::string>& opt) {
  for (int a = first; a < argc; a += 2) {
    if (!opt.count(argv[a])) {
      std::fprintf(stderr, "%s: unknown option %s\n", program, argv[a]);
      return false;
    }
    if (a + 1 >= argc) {
      std::fprintf(stderr, "%s: option %s needs a value\n", program, argv[a]);
      return false;
    }
    opt[argv[a]] = argv[a + 1];
  }
  return true;
}

// CPU seconds this process has used (all threads).
inline double cpu_seconds() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return t.tv_sec + 1e-9 * t.tv_nsec;
}

}  // namespace bench

// Numbers given on a command line: the whole word must be the number, and a bad one is named
// with its option and what the option expects ("--wait: 'soon' is not a number; expected
// seconds >= 0 (0: wait forever)"), instead of std::stod's bare "stod".
#pragma once

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <stdexcept>
#include <string>

namespace cosim {

// A finite number; raises std::invalid_argument "<option>: '<text>' is not a number; expected
// <expects>" (also for trailing characters, "nan", "inf" and overflow).
inline double parse_number_arg(const std::string& option, const std::string& text,
                               const std::string& expects) {
  char* end = nullptr;
  errno = 0;
  const double v = std::strtod(text.c_str(), &end);
  if (text.empty() || end != text.c_str() + text.size() || errno == ERANGE || !std::isfinite(v))
    throw std::invalid_argument(option + ": '" + text + "' is not a number; expected " + expects);
  return v;
}

// A number in [lo, hi]; the message names the range as `expects` says it.
inline double parse_number_arg(const std::string& option, const std::string& text,
                               const std::string& expects, double lo, double hi) {
  const double v = parse_number_arg(option, text, expects);
  if (!(v >= lo && v <= hi))
    throw std::invalid_argument(option + ": " + text + " is out of range; expected " + expects);
  return v;
}

// A whole number in [lo, hi] (decimal digits, optional sign).
inline long long parse_integer_arg(const std::string& option, const std::string& text,
                                   const std::string& expects, long long lo, long long hi) {
  char* end = nullptr;
  errno = 0;
  const long long v = std::strtoll(text.c_str(), &end, 10);
  if (text.empty() || end != text.c_str() + text.size() || errno == ERANGE)
    throw std::invalid_argument(option + ": '" + text + "' is not a whole number; expected " + expects);
  if (v < lo || v > hi)
    throw std::invalid_argument(option + ": " + text + " is out of range; expected " + expects);
  return v;
}

}  // namespace cosim

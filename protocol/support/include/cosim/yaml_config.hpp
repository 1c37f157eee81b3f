// Helpers every process uses to read YAML configs strictly: unknown keys, wrong types and
// out-of-range values are refused with a message that names the dotted key and what is allowed.
#pragma once

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <initializer_list>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace cosim::config {

struct ConfigError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// Reads a YAML config file. Raises ConfigError naming the file (and line) when it is missing, a
// folder, not valid YAML, has the same key twice in a map or a key that is not a plain name, or
// its top level is not a map (an empty file gives a null node: every key takes its default).
YAML::Node load_file(const std::string& path);
// The same checks on text in memory; `name` stands for the file in messages.
YAML::Node load_string(const std::string& text, const std::string& name);

// Applies "a.b.c=value" (from --set) to root: the value is parsed as YAML, so numbers, lists
// and maps work. Intermediate maps are created. A malformed assignment raises ConfigError.
void apply_override(YAML::Node& root, const std::string& assignment);

// Applies a map of overrides {"a.b.c": value, ...} as apply_override does for each entry, in
// map order. A map value amends the map it names key by key ({a: {b: 1}} is a.b=1 and keeps
// a's other keys); a list or scalar replaces. How a participant's `parameters` from the master's config amend its own config
// file. `what` names the map in errors (e.g. "participants.dem.parameters").
void apply_overrides(YAML::Node& root, const YAML::Node& overrides, std::string_view what);

// Raises ConfigError "<path>.k: unknown key 'k' (allowed: a, b, c)" for keys not in allowed,
// followed by "; did you mean 'b'?" when closest_key finds one, and "<path>: expected a map"
// if node is not a map. path is the dotted path of node.
void check_keys(const YAML::Node& node, std::string_view path,
                std::initializer_list<std::string_view> allowed);
void check_keys(const YAML::Node& node, std::string_view path,
                const std::vector<std::string>& allowed);

// The allowed key a misspelt `key` most likely means: the only one within one edit
// (insertion, deletion or substitution; ASCII case ignored) for keys under six characters, two
// edits for longer ones. "" when none or several are that close.
std::string closest_key(std::string_view key, const std::vector<std::string>& allowed);

std::string join_path(std::string_view parent, std::string_view key);

// Typed access. `required` raises ConfigError "<path>.<key>: missing (expected <what>)";
// a value of the wrong type raises "<path>.<key>: expected <type>, got '<text>'".
double get_double(const YAML::Node& node, std::string_view path, const std::string& key);
double get_double_or(const YAML::Node& node, std::string_view path, const std::string& key,
                     double fallback);
// A finite double with min <= value (strictly > min if min_exclusive).
double get_positive(const YAML::Node& node, std::string_view path, const std::string& key);
double get_positive_or(const YAML::Node& node, std::string_view path, const std::string& key,
                       double fallback);
long long get_int(const YAML::Node& node, std::string_view path, const std::string& key);
long long get_int_or(const YAML::Node& node, std::string_view path, const std::string& key,
                     long long fallback);
bool get_bool_or(const YAML::Node& node, std::string_view path, const std::string& key,
                 bool fallback);
std::string get_string(const YAML::Node& node, std::string_view path, const std::string& key);
std::string get_string_or(const YAML::Node& node, std::string_view path, const std::string& key,
                          const std::string& fallback);
// One of `allowed`, else "<path>.<key>: 'x' is not allowed (allowed: a, b)".
std::string get_choice(const YAML::Node& node, std::string_view path, const std::string& key,
                       std::initializer_list<std::string_view> allowed,
                       const std::string& fallback = {});
// A fixed-size list of finite doubles, e.g. a 3-vector.
std::vector<double> get_vector(const YAML::Node& node, std::string_view path,
                               const std::string& key, std::size_t size);

}  // namespace cosim::config

#include "cosim/yaml_config.hpp"

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>

namespace cosim::config {
namespace {

std::string list(std::initializer_list<std::string_view> items) {
  std::string out;
  for (auto item : items) {
    if (!out.empty()) out += ", ";
    out += item;
  }
  return out;
}

std::string describe(const YAML::Node& value) {
  if (!value.IsDefined() || value.IsNull()) return "null";
  if (value.IsScalar()) return value.Scalar();
  if (value.IsSequence()) return "a list";
  return "a map";
}

// Levenshtein distance, ASCII case-insensitive (a typo of case counts as no edit).
std::size_t edit_distance(std::string_view a, std::string_view b) {
  auto lower = [](char c) { return c >= 'A' && c <= 'Z' ? static_cast<char>(c - 'A' + 'a') : c; };
  std::vector<std::size_t> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    std::size_t diagonal = row[0];
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t above = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1,
                         diagonal + (lower(a[i - 1]) == lower(b[j - 1]) ? 0 : 1)});
      diagonal = above;
    }
  }
  return row[b.size()];
}

YAML::Node required(const YAML::Node& node, std::string_view path, const std::string& key,
                    const char* what) {
  if (!node.IsMap() || !node[key])
    throw ConfigError(join_path(path, key) + ": missing (expected " + what + ")");
  return node[key];
}

}  // namespace

std::string join_path(std::string_view parent, std::string_view key) {
  if (parent.empty()) return std::string(key);
  return std::string(parent) + "." + std::string(key);
}

namespace {

std::string at(const std::string& name, const YAML::Mark& m) {
  return name + ":" + std::to_string(m.line + 1) + ":" + std::to_string(m.column + 1);
}

// Refuses what yaml-cpp accepts but a config never means: the same key twice in one map (yaml-cpp
// keeps both and a lookup sees only the first) and keys that are lists or maps. Counts nodes so
// aliases that multiply a document cannot make the walk run away.
void check_document(const YAML::Node& node, const std::string& name, std::size_t& budget) {
  if (budget == 0)
    throw ConfigError(name + ": more than 1,000,000 values (aliases that repeat each other?): "
                             "write the config out without nested aliases");
  --budget;
  if (node.IsSequence()) {
    for (const auto& item : node) check_document(item, name, budget);
  } else if (node.IsMap()) {
    std::vector<std::pair<std::string, YAML::Mark>> seen;
    for (const auto& kv : node) {
      if (!kv.first.IsScalar())
        throw ConfigError(at(name, kv.first.Mark()) + ": a key must be a plain name, got " +
                          describe(kv.first) + ": write 'name: value'");
      const std::string& key = kv.first.Scalar();
      for (const auto& [k, mark] : seen)
        if (k == key)
          throw ConfigError(at(name, kv.first.Mark()) + ": duplicate key '" + key +
                            "' (first at line " + std::to_string(mark.line + 1) +
                            "): a key may appear once in a map; remove or merge one of them");
      seen.emplace_back(key, kv.first.Mark());
      check_document(kv.second, name, budget);
    }
  }
}

YAML::Node checked_root(YAML::Node root, const std::string& name) {
  std::size_t budget = 1000000;
  check_document(root, name, budget);
  if (root.IsNull()) return root;  // an empty file: every key takes its default
  if (!root.IsMap())
    throw ConfigError(name + ": expected a map of 'key: value' lines at the top level, got " +
                      (root.IsScalar() ? "the single value '" + root.Scalar() + "'" : describe(root)) +
                      ": is this the right file? (docs/config.md, docs/dem.md)");
  return root;
}

YAML::Node parse(const std::string& text, const std::string& name) {
  try {
    return YAML::Load(text);
  } catch (const YAML::ParserException& e) {
    std::ostringstream msg;
    msg << name << ":" << e.mark.line + 1 << ":" << e.mark.column + 1
        << ": not valid YAML: " << e.msg;
    throw ConfigError(msg.str());
  } catch (const YAML::Exception& e) {  // e.g. nesting too deep
    throw ConfigError(name + ": not valid YAML: " + e.msg);
  }
}

}  // namespace

YAML::Node load_file(const std::string& path) {
  std::error_code ec;
  const auto status = std::filesystem::status(path, ec);
  if (status.type() == std::filesystem::file_type::directory)
    throw ConfigError("config file '" + path + "' is a folder, not a file: give the YAML file "
                      "itself (e.g. " + (std::filesystem::path(path) / "config.yaml").string() + ")");
  if (status.type() == std::filesystem::file_type::not_found)
    throw ConfigError("cannot read config file '" + path + "': it does not exist; check the path");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw ConfigError("cannot read config file '" + path + "': check the path and its permissions");
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) throw ConfigError("cannot read config file '" + path + "': read error");
  return checked_root(parse(text.str(), path), path);
}

YAML::Node load_string(const std::string& text, const std::string& name) {
  return checked_root(parse(text, name), name);
}

void apply_overrides(YAML::Node& root, const YAML::Node& overrides, std::string_view what) {
  if (!overrides || overrides.IsNull()) return;
  if (!overrides.IsMap())
    throw ConfigError(std::string(what) + ": expected a map of dotted.key: value overrides");
  // A map value amends the map it names key by key (so {contact: {k: 1}} keeps contact's
  // other keys); anything else replaces.
  std::function<void(const std::string&, const YAML::Node&)> apply =
      [&](const std::string& key, const YAML::Node& value) {
        if (value.IsMap() && value.size() > 0) {
          for (const auto& e : value) apply(key + "." + e.first.as<std::string>(), e.second);
          return;
        }
        YAML::Emitter out;
        out << YAML::Flow << value;
        try {
          apply_override(root, key + "=" + out.c_str());
        } catch (const ConfigError& e) {
          throw ConfigError(std::string(what) + ": " + e.what());
        }
      };
  for (const auto& entry : overrides) apply(entry.first.as<std::string>(), entry.second);
}

void apply_override(YAML::Node& root, const std::string& assignment) {
  const auto eq = assignment.find('=');
  if (eq == std::string::npos || eq == 0)
    throw ConfigError("--set '" + assignment + "': expected dotted.key=value");
  const std::string key = assignment.substr(0, eq);
  YAML::Node value;
  try {
    value = YAML::Load(assignment.substr(eq + 1));
  } catch (const YAML::ParserException& e) {
    throw ConfigError("--set " + key + ": value is not valid YAML: " + e.msg);
  }
  std::vector<std::string> parts;
  std::size_t start = 0;
  while (true) {
    const auto dot = key.find('.', start);
    parts.push_back(key.substr(start, dot - start));
    if (dot == std::string::npos) break;
    start = dot + 1;
  }
  for (const auto& part : parts)
    if (part.empty()) throw ConfigError("--set '" + assignment + "': empty key segment");
  if (!root || root.IsNull()) root = YAML::Node(YAML::NodeType::Map);
  // A numeric segment indexes a list (connections.2.predictor=...).
  auto index_of = [&](const YAML::Node& node, const std::string& part) -> long {
    if (!node.IsSequence()) return -1;
    char* end = nullptr;
    const long i = std::strtol(part.c_str(), &end, 10);
    if (*end != '\0' || i < 0 || static_cast<std::size_t>(i) >= node.size())
      throw ConfigError("--set " + key + ": '" + part + "' is not an index of that list (it has " +
                        std::to_string(node.size()) + " entries)");
    return i;
  };
  // yaml-cpp nodes are handles: walking with operator[] on copies edits the same tree.
  std::vector<YAML::Node> chain{root};
  for (std::size_t i = 0; i + 1 < parts.size(); ++i) {
    YAML::Node parent = chain.back();
    const long index = index_of(parent, parts[i]);
    YAML::Node child = index >= 0 ? parent[static_cast<std::size_t>(index)] : parent[parts[i]];
    if (child.IsDefined() && !child.IsNull() && !child.IsMap() && !child.IsSequence())
      throw ConfigError("--set " + key + ": '" + parts[i] + "' is not a map or a list");
    if (!child.IsDefined() || child.IsNull()) {
      parent[parts[i]] = YAML::Node(YAML::NodeType::Map);
      child = parent[parts[i]];
    }
    chain.push_back(child);
  }
  const long last = index_of(chain.back(), parts.back());
  if (last >= 0) chain.back()[static_cast<std::size_t>(last)] = value;
  else chain.back()[parts.back()] = value;
}

std::string closest_key(std::string_view key, const std::vector<std::string>& allowed) {
  // Up to one edit in short keys, two from six characters on: closer than that, a typo;
  // farther, a different word.
  const std::size_t limit = key.size() < 6 ? 1 : 2;
  std::size_t best = limit + 1;
  std::string match;
  bool tie = false;
  for (const auto& a : allowed) {
    const std::size_t d = edit_distance(key, a);
    if (d < best) {
      best = d;
      match = a;
      tie = false;
    } else if (d == best) {
      tie = true;
    }
  }
  return best <= limit && !tie ? match : std::string();
}

void check_keys(const YAML::Node& node, std::string_view path,
                std::initializer_list<std::string_view> allowed) {
  check_keys(node, path, std::vector<std::string>(allowed.begin(), allowed.end()));
}

void check_keys(const YAML::Node& node, std::string_view path,
                const std::vector<std::string>& allowed) {
  if (!node.IsMap())
    throw ConfigError(std::string(path.empty() ? "config" : path) + ": expected a map, got " +
                      describe(node));
  for (const auto& kv : node) {
    const auto key = kv.first.as<std::string>();
    bool ok = false;
    std::string names;
    for (const auto& a : allowed) {
      ok = ok || a == key;
      names += (names.empty() ? "" : ", ") + a;
    }
    if (!ok) {
      const std::string hint = closest_key(key, allowed);
      throw ConfigError(join_path(path, key) + ": unknown key '" + key + "' (allowed: " +
                        names + ")" + (hint.empty() ? "" : "; did you mean '" + hint + "'?"));
    }
  }
}

double get_double(const YAML::Node& node, std::string_view path, const std::string& key) {
  const auto value = required(node, path, key, "a number");
  double out = 0;
  if (!value.IsScalar() || !YAML::convert<double>::decode(value, out) || !std::isfinite(out))
    throw ConfigError(join_path(path, key) + ": expected a finite number, got '" +
                      describe(value) + "'");
  return out;
}

double get_double_or(const YAML::Node& node, std::string_view path, const std::string& key,
                     double fallback) {
  if (!node.IsMap() || !node[key]) return fallback;
  return get_double(node, path, key);
}

double get_positive(const YAML::Node& node, std::string_view path, const std::string& key) {
  const double v = get_double(node, path, key);
  if (!(v > 0))
    throw ConfigError(join_path(path, key) + ": must be > 0, got " + describe(node[key]));
  return v;
}

double get_positive_or(const YAML::Node& node, std::string_view path, const std::string& key,
                       double fallback) {
  if (!node.IsMap() || !node[key]) return fallback;
  return get_positive(node, path, key);
}

long long get_int(const YAML::Node& node, std::string_view path, const std::string& key) {
  const auto value = required(node, path, key, "an integer");
  long long out = 0;
  if (!value.IsScalar() || !YAML::convert<long long>::decode(value, out))
    throw ConfigError(join_path(path, key) + ": expected an integer, got '" + describe(value) +
                      "'");
  return out;
}

long long get_int_or(const YAML::Node& node, std::string_view path, const std::string& key,
                     long long fallback) {
  if (!node.IsMap() || !node[key]) return fallback;
  return get_int(node, path, key);
}

bool get_bool_or(const YAML::Node& node, std::string_view path, const std::string& key,
                 bool fallback) {
  if (!node.IsMap() || !node[key]) return fallback;
  bool out = false;
  if (!node[key].IsScalar() || !YAML::convert<bool>::decode(node[key], out))
    throw ConfigError(join_path(path, key) + ": expected true or false, got '" +
                      describe(node[key]) + "'");
  return out;
}

std::string get_string(const YAML::Node& node, std::string_view path, const std::string& key) {
  const auto value = required(node, path, key, "a string");
  if (!value.IsScalar())
    throw ConfigError(join_path(path, key) + ": expected a string, got " + describe(value));
  return value.Scalar();
}

std::string get_string_or(const YAML::Node& node, std::string_view path, const std::string& key,
                          const std::string& fallback) {
  if (!node.IsMap() || !node[key] || node[key].IsNull()) return fallback;
  return get_string(node, path, key);
}

std::string get_choice(const YAML::Node& node, std::string_view path, const std::string& key,
                       std::initializer_list<std::string_view> allowed,
                       const std::string& fallback) {
  const std::string value = fallback.empty() ? get_string(node, path, key)
                                             : get_string_or(node, path, key, fallback);
  for (auto a : allowed)
    if (a == value) return value;
  throw ConfigError(join_path(path, key) + ": '" + value + "' is not allowed (allowed: " +
                    list(allowed) + ")");
}

std::vector<double> get_vector(const YAML::Node& node, std::string_view path,
                               const std::string& key, std::size_t size) {
  const auto value = required(node, path, key, "a list of numbers");
  const auto where = join_path(path, key);
  if (!value.IsSequence() || value.size() != size)
    throw ConfigError(where + ": expected a list of " + std::to_string(size) + " numbers, got " +
                      describe(value));
  std::vector<double> out(size);
  for (std::size_t i = 0; i < size; ++i) {
    if (!value[i].IsScalar() || !YAML::convert<double>::decode(value[i], out[i]) ||
        !std::isfinite(out[i]))
      throw ConfigError(where + "[" + std::to_string(i) + "]: expected a finite number, got '" +
                        describe(value[i]) + "'");
  }
  return out;
}

}  // namespace cosim::config

#include "config.hpp"

#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

namespace master {

namespace cfg = cosim::config;
using cfg::ConfigError;

const ParticipantSpec& Config::participant(const std::string& name) const {
  for (const auto& p : participants)
    if (p.name == name) return p;
  throw ConfigError("no participant named '" + name + "'");
}

namespace {

Endpoint parse_endpoint(const YAML::Node& node, const std::string& path, const std::string& key,
                        const Config& c) {
  const std::string text = cfg::get_string(node, path, key);
  const auto dot = text.find('.');
  const std::string where = cfg::join_path(path, key);
  if (dot == std::string::npos || text.find('.', dot + 1) != std::string::npos)
    throw ConfigError(where + ": '" + text + "' must be participant.signal");
  Endpoint e{text.substr(0, dot), text.substr(dot + 1)};
  std::string names;
  bool known = false;
  for (const auto& p : c.participants) {
    known = known || p.name == e.participant;
    names += (names.empty() ? "" : ", ") + p.name;
  }
  if (!known)
    throw ConfigError(where + ": no participant '" + e.participant + "' (participants: " + names + ")");
  if (!cosim::valid_name(e.signal))
    throw ConfigError(where + ": '" + e.signal + "' is not a valid signal name");
  return e;
}

PredictorSpec parse_predictor(const YAML::Node& node, const std::string& path) {
  cfg::check_keys(node, path, {"order", "samples"});
  PredictorSpec p;
  const long long order = cfg::get_int(node, path, "order");
  if (order < 0 || order > cosim::kMaxPolynomialOrder)
    throw ConfigError(path + ".order: " + std::to_string(order) + " is not allowed (allowed: 0, 1, 2, 3)");
  p.order = static_cast<int>(order);
  const long long samples = cfg::get_int_or(node, path, "samples", order + 1);
  if (samples < order + 1 || samples > 16)
    throw ConfigError(path + ".samples: " + std::to_string(samples) + " is not allowed (allowed: " +
                      std::to_string(order + 1) + " to 16; more than order + 1 gives a least-squares fit)");
  p.samples = static_cast<int>(samples);
  return p;
}

double seconds_key(const YAML::Node& n, const std::string& path, const std::string& key) {
  return cfg::get_double(n, path, key);
}

}  // namespace

Config parse_config(const YAML::Node& root, const std::string& source_text) {
  Config c;
  c.source_text = source_text;
  {
    YAML::Emitter out;
    out << root;
    c.effective_yaml = out.c_str();
  }
  cfg::check_keys(root, "", {"bus", "time", "scheme", "order", "startup_iterations",
                              "connect_timeout", "participants", "predictors", "connections",
                              "power", "output", "faults"});
  // bus
  if (root["bus"]) {
    cfg::check_keys(root["bus"], "bus", {"url"});
    c.bus_url = cfg::get_string_or(root["bus"], "bus", "url", "");
  }
  // time
  if (!root["time"]) throw ConfigError("time: missing (expected a map with start, end, macro_step)");
  const auto& time = root["time"];
  cfg::check_keys(time, "time", {"start", "end", "macro_step"});
  c.t_start = cosim::seconds_to_time_point(cfg::get_double_or(time, "time", "start", 0.0), "time.start");
  c.t_end = cosim::seconds_to_time_point(seconds_key(time, "time", "end"), "time.end");
  c.macro_step = cosim::seconds_to_duration(seconds_key(time, "time", "macro_step"), "time.macro_step");
  if (c.macro_step <= Duration::zero()) throw ConfigError("time.macro_step: must be > 0");
  if (c.t_end <= c.t_start) throw ConfigError("time.end: must be after time.start");
  if ((c.t_end - c.t_start) % c.macro_step != Duration::zero())
    throw ConfigError("time.end: end - start must be a whole number of macro steps (time.macro_step = " +
                      std::to_string(cosim::to_seconds(c.macro_step)) + " s)");
  // scheme
  const std::string scheme = cfg::get_choice(root, "", "scheme", {"jacobi", "gauss_seidel"}, "jacobi");
  c.scheme = scheme == "jacobi" ? Scheme::Jacobi : Scheme::GaussSeidel;
  const long long iters = cfg::get_int_or(root, "", "startup_iterations", 2);
  if (iters < 0 || iters > 20)
    throw ConfigError("startup_iterations: " + std::to_string(iters) + " is not allowed (allowed: 0 to 20)");
  c.startup_iterations = static_cast<int>(iters);
  c.connect_timeout = cfg::get_positive_or(root, "", "connect_timeout", 30.0);
  // participants
  const auto& parts = root["participants"];
  if (!parts || !parts.IsMap() || parts.size() == 0)
    throw ConfigError("participants: missing (expected a map: name -> {launch, timeout, retries, parameters})");
  for (const auto& kv : parts) {
    ParticipantSpec p;
    p.name = kv.first.as<std::string>();
    const std::string path = "participants." + p.name;
    if (!cosim::valid_name(p.name) || p.name == "master")
      throw ConfigError(path + ": '" + p.name + "' is not a valid participant name (1 to 32 characters of A-Z, a-z, 0-9, _; not 'master')");
    const YAML::Node node = kv.second.IsNull() ? YAML::Node(YAML::NodeType::Map) : kv.second;
    cfg::check_keys(node, path, {"launch", "timeout", "retries", "parameters"});
    if (node["launch"] && !node["launch"].IsNull()) {  // null: started by the user
      if (!node["launch"].IsSequence() || node["launch"].size() == 0)
        throw ConfigError(path + ".launch: expected a non-empty list [program, arg, ...]");
      for (const auto& a : node["launch"]) {
        if (!a.IsScalar()) throw ConfigError(path + ".launch: every entry must be a string");
        p.launch.push_back(a.Scalar());
      }
    }
    p.link.timeout_s = cfg::get_positive_or(node, path, "timeout", 2.0);
    const long long retries = cfg::get_int_or(node, path, "retries", 3);
    if (retries < 0 || retries > 100)
      throw ConfigError(path + ".retries: " + std::to_string(retries) + " is not allowed (allowed: 0 to 100)");
    p.link.retries = static_cast<int>(retries);
    if (node["parameters"]) {
      if (!node["parameters"].IsMap() && !node["parameters"].IsNull())
        throw ConfigError(path + ".parameters: expected a map");
      YAML::Emitter out;
      out << node["parameters"];
      p.parameters_yaml = out.c_str();
    }
    c.participants.push_back(p);
  }
  // Gauss-Seidel order
  if (root["order"]) {
    if (!root["order"].IsSequence()) throw ConfigError("order: expected a list of participant names");
    for (const auto& n : root["order"]) c.order.push_back(n.as<std::string>());
  } else {
    for (const auto& p : c.participants) c.order.push_back(p.name);
  }
  {
    std::set<std::string> in_order(c.order.begin(), c.order.end());
    if (in_order.size() != c.order.size() || in_order.size() != c.participants.size())
      throw ConfigError("order: must list every participant exactly once");
    for (const auto& n : c.order) c.participant(n);  // raises for unknown names
  }
  // named predictors
  std::map<std::string, PredictorSpec> named;
  if (root["predictors"]) {
    if (!root["predictors"].IsMap()) throw ConfigError("predictors: expected a map name -> {order, samples}");
    for (const auto& kv : root["predictors"]) {
      const auto name = kv.first.as<std::string>();
      named[name] = parse_predictor(kv.second, "predictors." + name);
    }
  }
  // connections
  const auto& conns = root["connections"];
  if (!conns || !conns.IsSequence() || conns.size() == 0)
    throw ConfigError("connections: missing (expected a list of {from: p.signal, to: p.signal, predictor: ...})");
  std::set<std::string> inputs_seen;
  for (std::size_t i = 0; i < conns.size(); ++i) {
    const std::string path = "connections." + std::to_string(i);
    cfg::check_keys(conns[i], path, {"from", "to", "predictor"});
    ConnectionSpec k;
    k.from = parse_endpoint(conns[i], path, "from", c);
    k.to = parse_endpoint(conns[i], path, "to", c);
    if (k.from.participant == k.to.participant)
      throw ConfigError(path + ": a participant cannot feed itself (" + k.from.str() + " -> " + k.to.str() + ")");
    if (!inputs_seen.insert(k.to.str()).second)
      throw ConfigError(path + ".to: input " + k.to.str() + " is connected twice");
    const auto& pred = conns[i]["predictor"];
    if (!pred) {
      k.predictor = PredictorSpec{};
    } else if (pred.IsScalar()) {
      k.predictor_name = pred.Scalar();
      auto it = named.find(k.predictor_name);
      if (it == named.end()) {
        std::string names;
        for (const auto& [n, s] : named) names += (names.empty() ? "" : ", ") + n;
        throw ConfigError(path + ".predictor: unknown predictor '" + k.predictor_name +
                          "' (defined under predictors: " + (names.empty() ? "none" : names) + ")");
      }
      k.predictor = it->second;
    } else {
      k.predictor = parse_predictor(pred, path + ".predictor");
    }
    c.connections.push_back(k);
  }
  // power pairs
  if (root["power"]) {
    if (!root["power"].IsSequence()) throw ConfigError("power: expected a list of {name, force, velocity}");
    for (std::size_t i = 0; i < root["power"].size(); ++i) {
      const std::string path = "power." + std::to_string(i);
      const auto& n = root["power"][i];
      cfg::check_keys(n, path, {"name", "force", "velocity"});
      PowerSpec p;
      p.force = parse_endpoint(n, path, "force", c);
      p.velocity = parse_endpoint(n, path, "velocity", c);
      p.name = cfg::get_string_or(n, path, "name", p.force.str() + "_x_" + p.velocity.str());
      c.power.push_back(p);
    }
  }
  // output
  if (root["output"]) {
    const auto& o = root["output"];
    cfg::check_keys(o, "output", {"file", "csv", "progress"});
    c.output.file = cfg::get_string_or(o, "output", "file", "");
    c.output.csv_file = cfg::get_string_or(o, "output", "csv", "");
    c.output.progress = cfg::get_choice(o, "output", "progress", {"auto", "on", "off"}, "auto");
  }
  // faults (tests): lose a request or reply once
  if (root["faults"]) {
    const auto& f = root["faults"];
    cfg::check_keys(f, "faults", {"drop_request", "drop_reply"});
    for (const char* key : {"drop_request", "drop_reply"}) {
      if (!f[key]) continue;
      if (!f[key].IsSequence()) throw ConfigError(std::string("faults.") + key + ": expected a list of {participant, step}");
      for (std::size_t i = 0; i < f[key].size(); ++i) {
        const std::string path = std::string("faults.") + key + "." + std::to_string(i);
        cfg::check_keys(f[key][i], path, {"participant", "step"});
        const auto who = cfg::get_string(f[key][i], path, "participant");
        c.participant(who);
        const auto step = cfg::get_int(f[key][i], path, "step");
        (std::string(key) == "drop_request" ? c.faults.drop_request : c.faults.drop_reply)
            .insert({who, step});
      }
    }
  }
  return c;
}

namespace {

// Replaces ${config_dir} in every string under node (launch arguments and parameters name
// files beside the config, wherever the master is started from).
void substitute_config_dir(YAML::Node node, const std::string& dir) {
  if (node.IsScalar()) {
    std::string v = node.Scalar();
    const std::string key = "${config_dir}";
    bool changed = false;
    for (auto at = v.find(key); at != std::string::npos; at = v.find(key, at + dir.size())) {
      v.replace(at, key.size(), dir);
      changed = true;
    }
    if (changed) node = v;
  } else if (node.IsSequence()) {
    for (std::size_t i = 0; i < node.size(); ++i) substitute_config_dir(node[i], dir);
  } else if (node.IsMap()) {
    for (auto it = node.begin(); it != node.end(); ++it) substitute_config_dir(it->second, dir);
  }
}

}  // namespace

Config load_config(const std::string& path, const std::vector<std::string>& overrides) {
  std::ifstream in(path);
  if (!in) throw ConfigError("cannot read config file '" + path + "': check the path");
  std::stringstream text;
  text << in.rdbuf();
  YAML::Node root = cfg::load_file(path);
  for (const auto& o : overrides) cfg::apply_override(root, o);
  if (YAML::Node parts = root["participants"]; parts && parts.IsMap()) {
    const std::string dir = std::filesystem::absolute(path).parent_path().lexically_normal().string();
    for (auto it = parts.begin(); it != parts.end(); ++it)
      if (it->second.IsMap()) {
        if (YAML::Node l = it->second["launch"]) substitute_config_dir(l, dir);
        if (YAML::Node p = it->second["parameters"]) substitute_config_dir(p, dir);
      }
  }
  return parse_config(root, text.str());
}

void check_wiring(const Config& c, const std::map<std::string, cosim::ParticipantInfo>& parts) {
  auto ports_list = [](const cosim::Ports& ports) {
    std::string s;
    for (const auto& p : ports) s += (s.empty() ? "" : ", ") + p.name;
    return s.empty() ? std::string("none") : s;
  };
  auto find = [](const cosim::Ports& ports, const std::string& name) -> const cosim::PortSpec* {
    for (const auto& p : ports)
      if (p.name == name) return &p;
    return nullptr;
  };
  for (std::size_t i = 0; i < c.connections.size(); ++i) {
    const auto& k = c.connections[i];
    const std::string what = "connections." + std::to_string(i) + " (" + k.from.str() + " -> " + k.to.str() + ")";
    const auto& src = parts.at(k.from.participant);
    const auto& dst = parts.at(k.to.participant);
    const auto* out = find(src.outputs, k.from.signal);
    if (!out)
      throw ConfigError(what + ": " + k.from.participant + " has no output '" + k.from.signal +
                        "' (it has: " + ports_list(src.outputs) + ")");
    const auto* in = find(dst.inputs, k.to.signal);
    if (!in)
      throw ConfigError(what + ": " + k.to.participant + " has no input '" + k.to.signal +
                        "' (it has: " + ports_list(dst.inputs) + ")");
    if (in->kind != out->kind)
      throw ConfigError(what + ": output is " + std::string(cosim::kind_name(out->kind)) +
                        " but the input is " + std::string(cosim::kind_name(in->kind)));
  }
  for (const auto& [name, info] : parts) {
    for (const auto& in : info.inputs) {
      bool fed = false;
      for (const auto& k : c.connections) fed = fed || (k.to.participant == name && k.to.signal == in.name);
      if (!fed)
        throw ConfigError("connections: input " + name + "." + in.name +
                          " is not connected (add {from: <participant>.<output>, to: " + name + "." + in.name + "})");
    }
    if (c.macro_step % info.inner_step != Duration::zero())
      throw ConfigError("time.macro_step: " + std::to_string(cosim::to_ns(c.macro_step)) +
                        " ns is not a multiple of participant " + name + "'s inner step " +
                        std::to_string(cosim::to_ns(info.inner_step)) +
                        " ns; choose a multiple of it or change that participant's inner step");
  }
  for (std::size_t i = 0; i < c.power.size(); ++i) {
    const auto& p = c.power[i];
    const std::string what = "power." + std::to_string(i);
    const auto* f = find(parts.at(p.force.participant).outputs, p.force.signal);
    const auto* v = find(parts.at(p.velocity.participant).outputs, p.velocity.signal);
    if (!f || !v) throw ConfigError(what + ": force and velocity must be outputs of their participants");
    const bool ok = (f->kind == cosim::SignalKind::Scalar && v->kind == cosim::SignalKind::Scalar) ||
                    (f->kind == cosim::SignalKind::Wrench && v->kind == cosim::SignalKind::Kinematics);
    if (!ok) throw ConfigError(what + ": pair a scalar force with a scalar velocity, or a wrench with kinematics");
    bool f_to_v = false, v_to_f = false;
    for (const auto& k : c.connections) {
      f_to_v = f_to_v || (k.from.str() == p.force.str() && k.to.participant == p.velocity.participant);
      v_to_f = v_to_f || (k.from.str() == p.velocity.str() && k.to.participant == p.force.participant);
    }
    if (!f_to_v || !v_to_f)
      throw ConfigError(what + ": " + p.force.str() + " must feed " + p.velocity.participant + " and " +
                        p.velocity.str() + " must feed " + p.force.participant);
  }
}

}  // namespace master

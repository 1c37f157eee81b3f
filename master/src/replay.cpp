#include "replay.hpp"

#include <cosim/bus.hpp>
#include <cosim/files.hpp>
#include <cosim/h5.hpp>
#include <cosim/polynomial_wire.hpp>
#include <cosim/sealed_bus.hpp>

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <cstdio>
#include <cstring>
#include <iostream>
#include <set>
#include <sstream>

#include "bus_log.hpp"
#include "recorder.hpp"

namespace master::replay {

namespace {

std::string fmt_seconds(double s) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.9g", s);
  return buf;
}

std::string join(const std::vector<std::string>& v, const std::string& sep = ", ") {
  std::string s;
  for (const auto& x : v) s += (s.empty() ? "" : sep) + x;
  return s;
}

template <class M>
std::vector<std::uint8_t> encode(const M& m) {
  std::vector<std::uint8_t> b(static_cast<std::size_t>(m.getEncodedSize()));
  m.encode(b.data(), 0, static_cast<int>(b.size()));
  return b;
}

bool same_bits(const std::vector<double>& a, const std::vector<double>& b) {
  return a.size() == b.size() && (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(double)) == 0);
}

std::string number(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

// Where two polynomial sets first differ, for people.
std::string polynomial_difference(const cosim::polynomial_set_t& recorded, const cosim::polynomial_set_t& now) {
  cosim::Polynomials a, b;
  try {
    a = cosim::from_message(recorded, "recorded inputs");
    b = cosim::from_message(now, "inputs");
  } catch (const std::exception& e) {
    return std::string("the inputs differ (") + e.what() + ")";
  }
  for (const auto& [name, pa] : a) {
    auto it = b.find(name);
    if (it == b.end()) return "input '" + name + "' is recorded but not sent now";
    const auto& pb = it->second;
    if (pa.n_coefficients != pb.n_coefficients)
      return "input '" + name + "' has " + std::to_string(pb.n_coefficients) + " coefficient(s), the recorded one " +
             std::to_string(pa.n_coefficients);
    const int w = cosim::tangent_size(pa.kind);
    for (std::size_t i = 0; i < pa.coefficients.size() && i < pb.coefficients.size(); ++i)
      if (std::memcmp(&pa.coefficients[i], &pb.coefficients[i], sizeof(double)) != 0)
        return "input '" + name + "', coefficient " + std::to_string(i / static_cast<std::size_t>(w)) +
               " component " + std::to_string(i % static_cast<std::size_t>(w)) + ": recorded " +
               number(pa.coefficients[i]) + ", now " + number(pb.coefficients[i]);
    for (int k = 0; k < 4; ++k)
      if (std::memcmp(&pa.orientation_reference[k], &pb.orientation_reference[k], sizeof(double)) != 0)
        return "input '" + name + "', orientation reference component " + std::to_string(k) + ": recorded " +
               number(pa.orientation_reference[k]) + ", now " + number(pb.orientation_reference[k]);
  }
  for (const auto& [name, pb] : b)
    if (!a.count(name)) return "input '" + name + "' is sent now but not in the recorded request";
  return "the encoded inputs differ";
}

struct Raw {
  int64_t index;
  std::string channel;
  std::vector<std::uint8_t> data;
};

struct Record {  // one of the master's own records (COSIM_<session>_LOG)
  int64_t index;
  int64_t session;
  std::vector<std::uint8_t> data;
  std::string digest_before;  // of every event before it
};

// "COSIM_<16 hex>_<rest>"
bool session_channel(const std::string& ch, int64_t& session, std::string& rest) {
  if (ch.size() < 23 || ch.compare(0, 6, "COSIM_") != 0 || ch[22] != '_') return false;
  const std::string hex = ch.substr(6, 16);
  if (hex.find_first_not_of("0123456789abcdef") != std::string::npos) return false;
  session = static_cast<int64_t>(std::stoull(hex, nullptr, 16));
  rest = ch.substr(23);
  return true;
}

bool instance_configure_channel(const std::string& ch) {
  return ch.size() == 26 && ch.compare(0, 10, "COSIM_CFG_") == 0 &&
         ch.find_first_not_of("0123456789abcdef", 10) == std::string::npos;
}

// The participant and the kind of a session channel's rest ("mass2_REP" -> mass2, REP).
bool participant_channel(const std::string& rest, std::string& name, std::string& kind) {
  if (rest.size() < 5 || rest[rest.size() - 4] != '_') return false;
  kind = rest.substr(rest.size() - 3);
  if (kind != "RDY" && kind != "REQ" && kind != "REP" && kind != "CFG") return false;
  name = rest.substr(0, rest.size() - 4);
  return !name.empty();
}

std::string value_of(const std::vector<std::pair<std::string, std::string>>& kv, const std::string& key) {
  for (const auto& [k, v] : kv)
    if (k == key) return v;
  return "";
}

}  // namespace

bool Recording::played_side(const std::string& name) const {
  for (const auto& p : played)
    if (p == name) return true;
  return false;
}

namespace {

// Which participants run live (--replay-side) and which are played from the log.
void split_sides(const Options& o, const Config& config, Recording& r) {
  std::vector<std::string> names;
  for (const auto& p : config.participants) names.push_back(p.name);
  for (const auto& l : o.live) {
    bool known = false;
    for (const auto& n : names) known = known || n == l;
    if (!known)
      throw ReplayError("--replay-side '" + l + "': the config has no participant of that name (it has " +
                        join(names) + "); name the participant(s) to rerun live");
  }
  for (const auto& n : names) {
    bool live = false;
    for (const auto& l : o.live) live = live || l == n;
    (live ? r.live : r.played).push_back(n);
  }
  if (r.played.empty())
    throw ReplayError("--replay-side names every participant of the config (" + join(names) +
                      "): nothing is left to play from the log; name only the side(s) to rerun live");

}

// One pass over the file: the events of every session, the master's records and the digest.
struct Scan {
  std::map<int64_t, std::vector<Raw>> by_session;
  std::vector<Record> records;
  int64_t events = 0;
};

Scan scan_log(const std::string& path) {
  Scan out;
  LogDigest digest;
  out.events = read_lcm_log(path, [&](LogEvent& e) {
    int64_t s = 0;
    std::string rest;
    const bool in_session = session_channel(e.channel, s, rest);
    if (in_session && rest == "LOG") {
      out.records.push_back({e.index, s, e.data, digest.hex()});
    } else if (in_session) {
      out.by_session[s].push_back({e.index, e.channel, e.data});
    } else if (instance_configure_channel(e.channel)) {
      // A configure of a participant started by hand: the session is in the (claimed) payload.
      const std::uint8_t* p = e.data.data();
      std::size_t n = e.data.size();
      if (cosim::auth::looks_sealed(p, n)) {
        if (const auto u = cosim::auth::unverified_payload(p, n)) p = u->first, n = u->second;
      }
      cosim::configure_t c;
      if (c.decode(p, 0, static_cast<int>(n)) == static_cast<int>(n) && c.session_id != 0)
        out.by_session[c.session_id].push_back({e.index, e.channel, e.data});
    }
    digest.add(e.channel, e.data.data(), e.data.size());
  });

  return out;
}

// The master's records, opened with the key when sealed.
struct Opened {
  Record rec;
  std::vector<std::pair<std::string, std::string>> kv;
};

std::vector<Opened> open_records(const Options& o, const std::vector<Record>& records,
                                 const std::optional<cosim::auth::Key>& key) {
  std::vector<Opened> opened;
  std::optional<cosim::auth::Opener> record_opener;
  if (key) record_opener.emplace(*key);
  for (const auto& rec : records) {
    const std::string channel = log_record_channel(rec.session);
    std::string text;
    if (cosim::auth::looks_sealed(rec.data.data(), rec.data.size())) {
      if (!record_opener)
        throw ReplayError("the log '" + o.log + "' is the recording of a run with a key: its messages are sealed "
                          "(docs/security.md) and a replay checks each one. Give this master the run's key "
                          "($COSIM_KEY_FILE or $COSIM_KEY)");
      const auto op = record_opener->open(channel, {rec.session}, rec.data.data(), rec.data.size());
      if (op.verdict != cosim::auth::Verdict::ok)
        throw ReplayError("the log '" + o.log + "' does not match this master's key: its record at event " +
                          std::to_string(rec.index) + " is " + cosim::auth::to_string(op.verdict) +
                          " (sealed with another key, or changed after recording); give this master the key "
                          "of the recorded run");
      text.assign(reinterpret_cast<const char*>(op.payload), op.size);
    } else {
      text.assign(rec.data.begin(), rec.data.end());
    }
    const auto kv = parse_log_record(text);
    if (!kv)
      throw ReplayError("the log '" + o.log + "' is corrupt: event " + std::to_string(rec.index) + " on " + channel +
                        " is not a record of cosim_master --record");
    opened.push_back({rec, *kv});
  }

  return opened;
}

std::set<std::string> participants_of(std::map<int64_t, std::vector<Raw>>& by_session, int64_t s) {
  std::set<std::string> ps;
  for (const auto& e : by_session[s]) {
    int64_t s2;
    std::string rest, name, kind;
    if (session_channel(e.channel, s2, rest) && participant_channel(rest, name, kind) && kind != "CFG" &&
        kind != "REQ")
      ps.insert(name);
  }
  return ps;
}

// Which recorded run: --replay-session, else the one the master's header names, else the one
// session holding every played side.
int64_t choose_session(const Options& o, const Recording& r, std::map<int64_t, std::vector<Raw>>& by_session,
                       const std::vector<Opened>& opened) {
  auto describe_sessions = [&] {
    std::string s;
    for (auto& [id, evs] : by_session) {
      const auto ps = participants_of(by_session, id);
      s += (s.empty() ? "" : "; ") + cosim::id_hex(id) + " (" +
           (ps.empty() ? std::string("no participant") : join({ps.begin(), ps.end()})) + ")";
    }
    return s.empty() ? std::string("no session's messages at all") : "session(s) " + s;
  };
  std::set<int64_t> headers;
  for (const auto& op : opened)
    if (value_of(op.kv, "record") == "start") headers.insert(op.rec.session);
  if (o.session != 0) {
    if (!by_session.count(o.session))
      throw ReplayError("the log '" + o.log + "' holds no message of session " + cosim::id_hex(o.session) +
                        " (--replay-session): it is the recording of another run. It holds " + describe_sessions() +
                        ". The session of a recorded run is in its HDF5 file (/bus/recording/session) and in "
                        "the master's first line ('session ...')");
    return o.session;
  }
  if (headers.size() == 1) return *headers.begin();
  std::vector<int64_t> candidates;
  for (auto& [id, evs] : by_session) {
    const auto ps = participants_of(by_session, id);
    bool all = true;
    for (const auto& p : r.played) all = all && ps.count(p);
    if (all) candidates.push_back(id);
  }
  if (candidates.size() > 1) {
    std::vector<std::string> ids;
    for (auto id : candidates) ids.push_back(cosim::id_hex(id));
    throw ReplayError("the log '" + o.log + "' holds " + std::to_string(candidates.size()) + " runs with " +
                      join(r.played) + ": sessions " + join(ids) + "; choose one with --replay-session HEX");
  }
  if (candidates.empty())
    throw ReplayError("the log '" + o.log + "' holds no recorded run with participant(s) " + join(r.played) +
                      " to play: it holds " + describe_sessions() +
                      ". Is it the recording of this config's run? (--replay-side names the side(s) that run "
                      "live; every other participant of the config is played from the log)");
  return candidates.front();
}


// The master's records of the session: complete and unchanged?
void check_records(const Options& o, Recording& r, const std::vector<Opened>& opened, const std::vector<Raw>& events) {
  const int64_t S = r.session;
  const Opened* start = nullptr;
  const Opened* end = nullptr;
  for (const auto& op : opened) {
    if (op.rec.session != S) continue;
    const std::string what = value_of(op.kv, "record");
    if (what == "start" && !start) start = &op;
    if (what == "end" && !end) end = &op;
  }
  r.from_master = start != nullptr;
  if (end) {
    const std::string count = value_of(end->kv, "events"), dig = value_of(end->kv, "digest");
    if (count != std::to_string(end->rec.index) || dig != end->rec.digest_before)
      throw ReplayError("the log '" + o.log + "' is corrupt: its end record counts " + count +
                        " event(s) before it with digest " + dig + ", the file holds " +
                        std::to_string(end->rec.index) + " with digest " + end->rec.digest_before +
                        ": it was changed after recording (or damaged)");
    for (const auto& e : events)
      if (e.index > end->rec.index)
        throw ReplayError("the log '" + o.log + "' is corrupt: event " + std::to_string(e.index) + " (" + e.channel +
                          ") of the recorded session comes after the recording's end record: something was "
                          "added to the file after recording");
    r.complete = true;
    r.status = value_of(end->kv, "status");
  }

}

// Every message of the session (keyed or not, one way), checked and decoded into the recording.
void collect_messages(const Options& o, Recording& r, const std::vector<Raw>& events,
                      const std::optional<cosim::auth::Key>& key) {
  const int64_t S = r.session;
  std::size_t sealed = 0;
  for (const auto& e : events) sealed += cosim::auth::looks_sealed(e.data.data(), e.data.size()) ? 1 : 0;
  if (sealed != 0 && sealed != events.size())
    throw ReplayError("the log '" + o.log + "' is corrupt: session " + cosim::id_hex(S) + " mixes " +
                      std::to_string(sealed) + " sealed and " + std::to_string(events.size() - sealed) +
                      " plain messages (a run's messages are either all sealed with its key or none)");
  r.keyed = sealed != 0;
  if (r.keyed && !key)
    throw ReplayError("the log '" + o.log + "' is the recording of a run with a key: its messages are sealed "
                      "(docs/security.md) and a replay checks each one's tag before it uses it. Give this "
                      "master the run's key ($COSIM_KEY_FILE or $COSIM_KEY)");
  std::optional<cosim::auth::Opener> opener;
  if (r.keyed) opener.emplace(*key);

  for (const auto& e : events) {
    const std::string where = "event " + std::to_string(e.index) + " (" + e.channel + ")";
    const std::uint8_t* p = e.data.data();
    std::size_t n = e.data.size();
    const bool to_instance = instance_configure_channel(e.channel);
    if (opener) {
      const auto op = opener->open(e.channel, {to_instance ? int64_t{0} : S}, p, n);
      switch (op.verdict) {
        case cosim::auth::Verdict::ok:
          p = op.payload;
          n = op.size;
          break;
        case cosim::auth::Verdict::forged:
          throw ReplayError("the log '" + o.log + "': " + where + " does not match this master's key: it was sealed "
                            "with another key, or changed after recording. Give this master the key of the "
                            "recorded run; a changed log cannot be replayed");
        case cosim::auth::Verdict::other_session:
          throw ReplayError("the log '" + o.log + "' is corrupt: " + where + " is sealed for session " +
                            cosim::id_hex(op.session) + ", not " + cosim::id_hex(S) +
                            ": a message of another run was put into this run's channels");
        case cosim::auth::Verdict::replayed:
          throw ReplayError("the log '" + o.log + "' is corrupt: " + where +
                            " repeats a sealed message that came earlier in the log (sequence number " +
                            std::to_string(op.sequence) + " of " + op.sender + "): the log was edited");
        case cosim::auth::Verdict::malformed:
          throw ReplayError("the log '" + o.log + "' is corrupt: " + where + " is not a valid sealed envelope");
      }
    }
    int64_t s2 = 0;
    std::string rest, name, kind;
    if (to_instance) {
      kind = "CFG";
    } else {
      session_channel(e.channel, s2, rest);
      if (rest == "HB" || rest == "END") continue;
      if (!participant_channel(rest, name, kind)) continue;  // not of this protocol
    }
    auto decode = [&](auto& m, const char* type) {
      if (m.decode(p, 0, static_cast<int>(n)) != static_cast<int>(n))
        throw ReplayError("the log '" + o.log + "' is corrupt: " + where + " does not decode as " + type);
      if (m.session_id != S)
        throw ReplayError("the log '" + o.log + "' is corrupt: " + where + " carries session " +
                          cosim::id_hex(m.session_id) + " on a channel of session " + cosim::id_hex(S));
      if (!name.empty() && m.participant != name)
        throw ReplayError("the log '" + o.log + "' is corrupt: " + where + " names participant '" + m.participant +
                          "' on the channel of '" + name + "'");
    };
    if (kind == "CFG") {
      cosim::configure_t c;
      decode(c, "configure_t");
      auto& rp = r.participants[c.participant];
      if (!rp.configure) rp.configure = c;
    } else if (kind == "RDY") {
      cosim::ready_t m;
      decode(m, "ready_t");
      auto& rp = r.participants[name];
      if (!rp.ready || (!rp.ready->ok && m.ok)) rp.ready = m;
    } else if (kind == "REQ") {
      cosim::step_request_t m;
      decode(m, "step_request_t");
      r.participants[name].requests.emplace(StepKey{m.step_index, m.iteration}, m);
    } else if (kind == "REP") {
      cosim::step_reply_t m;
      decode(m, "step_reply_t");
      r.participants[name].replies.emplace(StepKey{m.step_index, m.iteration}, m);
    }
  }

}

// Against the config: every played side is there, with the same times and parameters, and
// with a reply to every step the config runs.
void check_against_config(const Options& o, const Config& config, Recording& r) {
  const int64_t S = r.session;
  const int64_t steps = (config.t_end - config.t_start) / config.macro_step;
  std::vector<std::string> recorded_names;
  for (const auto& [n, rp] : r.participants)
    if (rp.ready) recorded_names.push_back(n);
  for (const auto& name : r.played) {
    auto it = r.participants.find(name);
    if (it == r.participants.end() || !it->second.ready)
      throw ReplayError("the log '" + o.log + "' holds no participant '" + name + "' in session " + cosim::id_hex(S) +
                        " (it holds " + (recorded_names.empty() ? std::string("none") : join(recorded_names)) +
                        "): it is not a recording of this config's '" + name +
                        "'. Replay the log of a run with it, or rerun '" + name + "' live (--replay-side " + name + ")");
    const auto& rp = it->second;
    if (!rp.ready->ok)
      throw ReplayError("in the recording, participant '" + name + "' refused its configuration (" + rp.ready->error +
                        "): the log holds no step of it to play");
    const auto& spec = config.participant(name);
    if (rp.configure) {
      const auto& c = *rp.configure;
      if (c.t_start_ns != cosim::to_ns(config.t_start) || c.macro_step_ns != cosim::to_ns(config.macro_step))
        throw ReplayError("the recording ran from t = " + fmt_seconds(cosim::to_seconds(cosim::time_point_ns(c.t_start_ns))) +
                          " s with macro steps of " + fmt_seconds(cosim::to_seconds(cosim::nanoseconds(c.macro_step_ns))) +
                          " s, this config from t = " + fmt_seconds(cosim::to_seconds(config.t_start)) + " s with " +
                          fmt_seconds(cosim::to_seconds(config.macro_step)) +
                          " s: a replay takes the recorded steps; set time.start and time.macro_step to the recorded ones");
      if (c.t_end_ns < cosim::to_ns(config.t_end))
        throw ReplayError("the recording ran to t = " + fmt_seconds(cosim::to_seconds(cosim::time_point_ns(c.t_end_ns))) +
                          " s, this config to " + fmt_seconds(cosim::to_seconds(config.t_end)) +
                          " s: a replay cannot go beyond the recording; set time.end to at most " +
                          fmt_seconds(cosim::to_seconds(cosim::time_point_ns(c.t_end_ns))));
      if (c.parameters_yaml != spec.parameters_yaml)
        throw ReplayError("participants." + name + ".parameters differ from the recorded ones: a played side repeats "
                          "what it did and its parameters cannot change (recorded: " + c.parameters_yaml +
                          "; this config: " + spec.parameters_yaml +
                          "). Change only the live side's parameters, or rerun '" + name + "' live");
    } else {
      r.notes.push_back("the log holds no configure of '" + name +
                        "' (started by hand and recorded without COSIM_CFG_.*): its parameters and times are "
                        "not checked against the config");
    }
    for (int64_t k = 0; k < steps; ++k) {
      if (rp.replies.count({k, 0})) continue;
      std::string why;
      if (r.complete && r.status != "finished")
        why = "the recorded run stopped there (its end record: " + r.status + ")";
      else if (r.from_master && !r.complete)
        why = "the log has no end record: the recording was cut off (the master stopped without closing it, "
              "or the file was truncated at an event boundary)";
      else if (r.from_master)
        why = "the recorder missed it";
      else
        why = "the log ends there or lost the message (recorded with lcm-logger?)";
      throw ReplayError("the log '" + o.log + "' holds no reply of '" + name + "' to step " + std::to_string(k) +
                        " (t = " + fmt_seconds(cosim::to_seconds(config.t_start + config.macro_step * k)) +
                        " s) of the " + std::to_string(steps) + " this config runs: " + why +
                        ". Set time.end to at most " +
                        fmt_seconds(cosim::to_seconds(config.t_start + config.macro_step * k)) +
                        " or replay a complete recording");
    }
  }
}

}  // namespace

Recording load(const Options& o, const Config& config, const std::optional<cosim::auth::Key>& key) {
  Recording r;
  r.path = o.log;
  split_sides(o, config, r);
  Scan scan = scan_log(o.log);
  r.events = scan.events;
  const std::vector<Opened> opened = open_records(o, scan.records, key);
  r.session = choose_session(o, r, scan.by_session, opened);
  const std::vector<Raw>& events = scan.by_session[r.session];
  check_records(o, r, opened, events);
  collect_messages(o, r, events, key);
  check_against_config(o, config, r);
  if (r.from_master && !r.complete)
    r.notes.push_back("the log has no end record (the recording was cut off), but it holds every step this config runs");
  return r;
}

// ---------------------------------------------------------------------------------------------

ReplayTransport::ReplayTransport(std::unique_ptr<cosim::Transport> live, const Recording& recording)
    : live_(std::move(live)), rec_(recording) {
  stats_ = live_->stats();
}

std::string ReplayTransport::describe() const {
  return live_->describe() + " (replaying " + join(rec_.played) + " from " + rec_.path + ")";
}

std::map<std::string, cosim::ParticipantInfo> ReplayTransport::connect(const std::vector<cosim::configure_t>& configs,
                                                                       double timeout_s) {
  std::vector<cosim::configure_t> live;
  for (const auto& c : configs)
    if (!rec_.played_side(c.participant)) live.push_back(c);
  std::map<std::string, cosim::ParticipantInfo> out;
  if (!live.empty()) out = live_->connect(live, timeout_s);
  stats_ = live_->stats();
  for (const auto& c : configs) {
    if (!rec_.played_side(c.participant)) continue;
    out[c.participant] = accept_ready(*rec_.participants.at(c.participant).ready);
  }
  infos_ = out;
  return out;
}

void ReplayTransport::compare_request(const cosim::step_request_t& q) {
  const auto& rp = rec_.participants.at(q.participant);
  auto it = rp.requests.find({q.step_index, q.iteration});
  if (it == rp.requests.end()) {
    ++report_.requests_missing;  // the recorder missed it: nothing to compare
    return;
  }
  ++report_.requests_compared;
  if (report_.request.found()) return;
  const auto& r = it->second;
  std::string detail;
  if (r.t_start_ns != q.t_start_ns || r.t_end_ns != q.t_end_ns)
    detail = "the step's times differ from the recorded ones";
  else if (r.want_average != q.want_average)
    detail = "the recorded request asked for interval averages differently";
  else if (encode(r.inputs) != encode(q.inputs))
    detail = polynomial_difference(r.inputs, q.inputs);
  if (detail.empty()) return;
  Difference& d = report_.request;
  d.step = q.step_index;
  d.iteration = q.iteration;
  d.t = cosim::to_seconds(cosim::time_point_ns(q.t_start_ns));
  d.participant = q.participant;
  d.detail = detail;
  std::cerr << "cosim_master: replay: the request to '" << q.participant << "' at step " << d.step << " (iteration "
            << d.iteration << ", t = " << fmt_seconds(d.t) << " s) differs from the recorded one (" << detail
            << "): the run diverges from the recording here; from now on " << q.participant
            << "'s recorded replies answer inputs it was not given\n";
}

void ReplayTransport::compare_outputs(const cosim::step_request_t& q, const cosim::StepAnswer& a) {
  auto pit = rec_.participants.find(q.participant);
  if (pit == rec_.participants.end()) {
    ++report_.outputs_missing;
    return;
  }
  auto it = pit->second.replies.find({q.step_index, q.iteration});
  if (it == pit->second.replies.end() || it->second.status != cosim::step_reply_t::OK) {
    ++report_.outputs_missing;
    return;
  }
  ++report_.outputs_compared;
  if (report_.output.found()) return;
  cosim::Signals recorded;
  try {
    recorded = cosim::from_message(it->second.outputs, "recorded outputs");
  } catch (const std::exception&) {
    return;
  }
  std::string detail;
  for (const auto& [name, s] : a.outputs) {
    auto r = recorded.find(name);
    if (r == recorded.end()) {
      detail = "output '" + name + "' is not in the recorded reply";
      break;
    }
    if (!same_bits(r->second.value, s.value)) {
      for (std::size_t i = 0; i < s.value.size() && i < r->second.value.size(); ++i)
        if (std::memcmp(&s.value[i], &r->second.value[i], sizeof(double)) != 0) {
          detail = "output '" + name + "' component " + std::to_string(i) + ": recorded " +
                   number(r->second.value[i]) + ", now " + number(s.value[i]);
          break;
        }
      if (detail.empty()) detail = "output '" + name + "' has another size than the recorded one";
      break;
    }
  }
  if (detail.empty()) return;
  Difference& d = report_.output;
  d.step = q.step_index;
  d.iteration = q.iteration;
  d.t = cosim::to_seconds(cosim::time_point_ns(q.t_start_ns));
  d.participant = q.participant;
  d.detail = detail;
}

std::vector<cosim::StepAnswer> ReplayTransport::exchange(const std::vector<cosim::step_request_t>& requests) {
  std::vector<cosim::step_request_t> live;
  for (const auto& q : requests) {
    if (rec_.played_side(q.participant)) compare_request(q);
    else live.push_back(q);
  }
  std::vector<cosim::StepAnswer> live_answers;
  if (!live.empty()) live_answers = live_->exchange(live);
  stats_ = live_->stats();
  std::vector<cosim::StepAnswer> out;
  std::size_t next_live = 0;
  for (const auto& q : requests) {
    if (!rec_.played_side(q.participant)) {
      compare_outputs(q, live_answers[next_live]);
      out.push_back(std::move(live_answers[next_live++]));
      continue;
    }
    const auto& rp = rec_.participants.at(q.participant);
    auto it = rp.replies.find({q.step_index, q.iteration});
    if (it == rp.replies.end())
      throw cosim::LinkError(q.participant,
                             "the recording holds no reply of '" + q.participant + "' to step " +
                                 std::to_string(q.step_index) + " iteration " + std::to_string(q.iteration) +
                                 ": the replay asks for a step the recorded run did not take (scheme, "
                                 "startup_iterations or predictor orders other than the recording's?)");
    out.push_back(accept(q, it->second, infos_.at(q.participant), it->second.compute_seconds));
  }
  return out;
}

void ReplayTransport::terminate(bool error, const std::string& reason) { live_->terminate(error, reason); }

// ---------------------------------------------------------------------------------------------

std::string summary(const Recording& rec, const Report& rep) {
  std::ostringstream o;
  o << "replay of " << rec.path << " (session " << cosim::id_hex(rec.session)
    << (rec.keyed ? ", sealed messages checked with the key" : "") << "): " << join(rec.played)
    << " played from the log, " << (rec.live.empty() ? std::string("nothing") : join(rec.live)) << " live. ";
  if (rep.request.found()) {
    o << "It diverged from the recording at step " << rep.request.step << " (iteration " << rep.request.iteration
      << ", t = " << fmt_seconds(rep.request.t) << " s): the request to '" << rep.request.participant
      << "' differs from the recorded one (" << rep.request.detail << ")";
  } else {
    o << "It did not diverge: all " << rep.requests_compared << " request(s) to " << join(rec.played)
      << " were bit-identical to the recorded ones";
    if (rep.requests_missing > 0) o << " (" << rep.requests_missing << " not in the log, not compared)";
  }
  if (!rec.live.empty()) {
    if (rep.output.found())
      o << "; the outputs of '" << rep.output.participant << "' first differ from the recorded ones at step "
        << rep.output.step << " (iteration " << rep.output.iteration << "; " << rep.output.detail << ")";
    else
      o << "; the live side's outputs were bit-identical to the recorded ones in all " << rep.outputs_compared
        << " step(s) compared";
  }
  o << ".";
  return o.str();
}

namespace {

// The group `group` of the notes, open (created with its parents when missing); raises naming it.
hid_t open_note_group(hid_t file, const std::string& group) {
  if (const hid_t g = H5Gopen2(file, group.c_str(), H5P_DEFAULT); g >= 0) return g;
  cosim::h5::Handle lcpl(H5Pcreate(H5P_LINK_CREATE), H5Pclose);
  if (lcpl.ok()) H5Pset_create_intermediate_group(lcpl, 1);
  const hid_t g = H5Gcreate2(file, group.c_str(), lcpl, H5P_DEFAULT, H5P_DEFAULT);
  if (g < 0) throw std::runtime_error("cannot create the group '" + group + "'");
  return g;
}

void write_text(hid_t file, const std::string& group, const std::string& name, const std::string& value) {
  const cosim::h5::Handle g(open_note_group(file, group), H5Gclose);
  cosim::h5::write_string(g, name, value);
}

void write_note_number(hid_t file, const std::string& group, const std::string& name, double value) {
  const cosim::h5::Handle g(open_note_group(file, group), H5Gclose);
  cosim::h5::write(g, name, std::vector<double>{value});
}

}  // namespace

void RunNotes::on_finish(bool ok, const std::string& message) {
  if (recorder_) {
    recorder_->finish(ok ? "finished" : "stopped: " + message);
    std::cerr << "cosim_master: recorded " << recorder_->events() << " bus message(s) of session "
              << cosim::id_hex(recorder_->session()) << " to " << recorder_->path() << " (LCM log)";
    if (recorder_->dropped() > 0)
      std::cerr << "; dropped " << recorder_->dropped() << " datagram(s) that were not the run's ("
                << recorder_->dropped_text() << ")";
    std::cerr << "\n";
  }
  if (replay_ && recording_) std::cerr << "cosim_master: " << summary(*recording_, replay_->report()) << "\n";
  if (h5_.empty() || (!recorder_ && !(replay_ && recording_))) return;
  std::error_code missing;
  if (!std::filesystem::exists(h5_, missing)) return;  // not written (the run stopped before it)
  // Checked as every write of a record (docs/output.md#when-a-record-cannot-be-written): a
  // failure raises naming the file and the cause, and the run does not say "finished".
  // When the run failed already, that failure is the one reported; this one is printed.
  auto failure = [&](const std::string& message) {
    if (!ok) {
      std::cerr << "cosim_master: " << message << "\n";
      return;
    }
    throw std::runtime_error(message);
  };
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  const hid_t f = H5Fopen(h5_.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
  if (f < 0)
    return failure(cosim::write_failure(
        h5_, "cannot open it to add the run's notes (/bus/recording, /replay)"));
  try {
    write_notes(f);
    cosim::h5::flush(f, h5_);
  } catch (const std::exception& e) {
    H5Fclose(f);
    const std::string what = e.what();
    // cosim::h5::flush names the file already.
    return failure(what.rfind("cannot write '", 0) == 0 ? what : cosim::write_failure(h5_, what));
  }
  try {
    cosim::h5::close(f, h5_);
  } catch (const std::exception& e) {
    return failure(e.what());
  }
}

void RunNotes::write_notes(std::int64_t f) const {
  if (recorder_) {
    write_text(f, "bus/recording", "file", recorder_->path());
    write_text(f, "bus/recording", "session", cosim::id_hex(recorder_->session()));
    write_note_number(f, "bus/recording", "events", static_cast<double>(recorder_->events()));
    write_note_number(f, "bus/recording", "dropped", static_cast<double>(recorder_->dropped()));
  }
  if (replay_ && recording_) {
    const Report& rep = replay_->report();
    write_text(f, "replay", "log", recording_->path);
    write_text(f, "replay", "session", cosim::id_hex(recording_->session));
    write_text(f, "replay", "played", join(recording_->played, ","));
    write_text(f, "replay", "live", join(recording_->live, ","));
    write_note_number(f, "replay", "keyed", recording_->keyed ? 1 : 0);
    write_note_number(f, "replay", "complete_log", recording_->complete ? 1 : 0);
    write_note_number(f, "replay", "diverged", rep.request.found() ? 1 : 0);
    write_note_number(f, "replay", "diverged_at_step", static_cast<double>(rep.request.step));
    write_note_number(f, "replay", "diverged_at_iteration", rep.request.found() ? rep.request.iteration : -1);
    write_note_number(f, "replay", "diverged_at_time", rep.request.found() ? rep.request.t : std::nan(""));
    write_text(f, "replay", "diverged_detail", rep.request.detail);
    write_note_number(f, "replay", "outputs_differ_at_step", static_cast<double>(rep.output.step));
    write_note_number(f, "replay", "requests_compared", static_cast<double>(rep.requests_compared));
    write_note_number(f, "replay", "requests_missing", static_cast<double>(rep.requests_missing));
    write_note_number(f, "replay", "outputs_compared", static_cast<double>(rep.outputs_compared));
    write_text(f, "replay", "summary", summary(*recording_, rep));
  }
}

}  // namespace master::replay

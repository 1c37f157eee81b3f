// Master side over LCM: configure with repeats until ready, then request/reply per step.
// Every request goes out LinkSettings::copies times (redundancy: a lost copy costs nothing).
// A request without reply is resent after the participant's adaptive resend timeout
// (ResendTimer: measured round trips, backoff; not while its heartbeat says it works on the
// request); the participant answers a repeat from its cache. Whether a participant is alive is
// decided apart from that, by its heartbeats and replies (participants.<name>.timeout).
#include <cosim/announce_t.hpp>
#include <cosim/heartbeat_t.hpp>
#include <cosim/terminate_t.hpp>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <iostream>
#include <cmath>
#include <lcm/lcm-cpp.hpp>
#include <sstream>
#include <thread>
#include <tuple>

#include "cosim/bus.hpp"
#include "cosim/link.hpp"
#include "cosim/resend_timer.hpp"
#include "cosim/sealed_bus.hpp"
#include "cosim/stopwatch.hpp"

namespace cosim {
namespace {

using Clock = WallClock;

class LcmTransport final : public Transport {
 public:
  LcmTransport(const std::string& url, int64_t session, std::map<std::string, LinkSettings> links,
               std::optional<auth::Key> key, std::string program)
      : url_(url), lcm_(url), session_(session), links_(std::move(links)), program_(std::move(program)),
        bus_(lcm_, std::move(key), envelope_sender("master", session), program_) {
    stats_.auth = bus_.stats();
    if (!lcm_.good())
      throw LinkError("", "cannot open the bus '" + url +
                              "' (for multicast on loopback: ip route add 224.0.0.0/4 dev lo)");
    lcm_.subscribe(channel::announce(), &LcmTransport::on_announce, this);
    lcm_.subscribe(channel::heartbeat(session_), &LcmTransport::on_heartbeat, this);
    for (const auto& [name, s] : links_) {
      peers_[name];
      lcm_.subscribe(channel::ready(session_, name), &LcmTransport::on_ready, this);
      lcm_.subscribe(channel::reply(session_, name), &LcmTransport::on_reply, this);
    }
  }

  int64_t session() const override { return session_; }
  std::string describe() const override { return url_; }

  std::map<std::string, ParticipantInfo> connect(const std::vector<configure_t>& configs,
                                                 double timeout_s) override {
    const auto start = Clock::now();
    auto last_send = start - std::chrono::hours(1);
    std::map<std::string, ParticipantInfo> out;
    while (out.size() < configs.size()) {
      for (const auto& c : configs)
        if (!links_.at(c.participant).launched && !chosen_.count(c.participant)) choose(c.participant);
      if (seconds_since(last_send) > 0.5) {  // repeat: a configure may be lost, or early
        for (auto c : configs) {
          if (ready_.count(c.participant)) continue;
          if (links_.at(c.participant).launched) {  // started with --session: its own channel
            c.instance_id = 0;
            bus_.publish(channel::configure(session_, c.participant), session_, c);
            ++stats_.configure_sends[c.participant];
          } else if (auto it = chosen_.find(c.participant); it != chosen_.end()) {
            c.instance_id = it->second;
            bus_.publish(channel::configure(it->second), 0, c);  // before a session: 0
            ++stats_.configure_sends[c.participant];
          }
        }
        last_send = Clock::now();
      }
      pump(50);
      for (const auto& c : configs) {
        auto it = ready_.find(c.participant);
        if (it != ready_.end() && !out.count(c.participant)) {
          out[c.participant] = accept_ready(it->second);
          infos_[c.participant] = out[c.participant];
        }
      }
      if (seconds_since(start) > timeout_s) {
        std::ostringstream msg;
        std::string missing;
        for (const auto& c : configs)
          if (!out.count(c.participant)) missing += (missing.empty() ? "" : ", ") + c.participant;
        // Heard, but not authentic (or sealed, without a key): the key is the problem.
        const std::string unauthenticated = unauthenticated_text(configs, out);
        if (!unauthenticated.empty())
          msg << "participant(s) " << missing << " cannot join: within " << timeout_s << " s on bus "
              << url_ << " " << unauthenticated;
        else
          msg << "no answer from participant(s) " << missing << " within " << timeout_s
              << " s on bus " << url_ << ": start them with --name <name> --bus '" << url_
              << "', or give participants.<name>.launch in the config";
        std::string heard;
        for (const auto& [name, instances] : seen_)
          for (const auto& [id, a] : instances)
            heard += (heard.empty() ? "" : ", ") + describe_instance(a.announce) +
                     (taken_.count(id) ? " (taken by another run)"
                      : a.announce.reserved_session_id != 0 && a.announce.reserved_session_id != session_
                          ? " (started for session " + id_hex(a.announce.reserved_session_id) + ")"
                      : a.announce.protocol_version != kProtocolVersion
                          ? " (protocol version " + std::to_string(a.announce.protocol_version) + ")"
                          : "");
        if (!heard.empty()) msg << " (heard from: " << heard << ")";
        std::string first_missing = missing.substr(0, missing.find(','));
        throw LinkError(first_missing, msg.str());
      }
    }
    return out;
  }

  std::vector<StepAnswer> exchange(const std::vector<step_request_t>& requests) override {
    pending_.clear();
    exchange_start_ = Clock::now();
    for (const auto& q : requests) {
      Pending& p = pending_[q.participant];
      p.request = q;
      p.first_sent = p.sent = p.progress = Clock::now();
      send(p);
    }
    std::size_t done = 0;
    while (done < requests.size()) {
      // Wait for the next message, or until the earliest resend is due (at least 1 ms).
      double next = 0.02;
      for (auto& [name, p] : pending_)
        if (!p.reply) next = std::min(next, seconds_between(Clock::now(), resend_due(name, p)));
      pump(std::clamp(static_cast<int>(std::ceil(next * 1000)), 1, 20));
      done = 0;
      const auto now = Clock::now();
      for (auto& [name, p] : pending_) {
        if (p.reply) { ++done; continue; }
        const LinkSettings& s = links_.at(name);
        Peer& peer = peers_[name];
        // Liveness: silence counts from the exchange's start at the earliest, so time the
        // master spent elsewhere (recording) is not blamed on the participant.
        const auto heard = peer.heard ? std::max(*peer.heard, exchange_start_) : exchange_start_;
        if (seconds_between(heard, now) > s.timeout_s) throw stopped_answering(name, p, s);
        if (seconds_between(p.progress, now) > (s.retries + 1) * s.timeout_s)
          throw not_answering(name, p, s);
        if (!p.reply_lost && now < resend_due(name, p)) continue;
        p.reply_lost = false;
        ++p.request.attempt;
        ++stats_.resends;
        ++stats_.resends_to[name];
        p.sent = now;
        send(p);
      }
    }
    std::vector<StepAnswer> out;
    for (const auto& q : requests) {
      const Pending& p = pending_.at(q.participant);
      out.push_back(accept(q, *p.reply, infos_.at(q.participant), p.round_trip));
    }
    pending_.clear();
    for (const auto& [name, peer] : peers_) {
      stats_.resend_timeout_s[name] = peer.timer.base();
      stats_.srtt_s[name] = peer.timer.srtt();
    }
    return out;
  }

  void terminate(bool error, const std::string& reason) override {
    terminate_t t{};
    t.session_id = session_;
    t.error = error;
    t.reason = reason;
    // Best effort, but a lossy link must not leave participants waiting for their idle
    // timeout: six copies over 25 ms (at 20 % loss all are lost once in 15,000 times).
    for (int i = 0; i < 6; ++i) {
      if (i > 0) std::this_thread::sleep_for(std::chrono::milliseconds(5));
      bus_.publish(channel::terminate(session_), session_, t);
    }
  }

 private:
  static constexpr double kBeat = 0.25;  // s between a participant's heartbeats

  struct Peer {
    std::optional<Clock::time_point> heard;  // last message of any kind from it (this session)
    std::optional<heartbeat_t> beat;         // its last heartbeat
    Clock::time_point beat_at;
    std::optional<int64_t> replied_step;     // the last step it answered (this session)
    Clock::time_point replied_at;
    ResendTimer timer;
  };
  struct Pending {
    step_request_t request;
    Clock::time_point first_sent;
    Clock::time_point sent;      // the last copy
    Clock::time_point progress;  // first send, or the last busy heartbeat for this request
    std::optional<Clock::time_point> busy;  // last busy heartbeat for this request
    bool reply_lost = false;     // an idle heartbeat says the step is done: resend at once
    std::optional<step_reply_t> reply;
    double round_trip = 0;
  };

  // When the next copy of p's request is due: the adaptive timeout after the last copy, or
  // after the next heartbeat expected from a participant that said it works on the request.
  Clock::time_point resend_due(const std::string& name, const Pending& p) const {
    auto from = p.sent;
    if (p.busy) from = std::max(from, *p.busy + std::chrono::duration_cast<Clock::duration>(
                                                    std::chrono::duration<double>(kBeat)));
    const double wait = peers_.at(name).timer.timeout(p.request.attempt);
    return from + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(wait));
  }

  std::string step_text(const Pending& p) const {
    std::ostringstream o;
    o.precision(6);
    o << "step " << p.request.step_index << " (t = " << to_seconds(time_point_ns(p.request.t_start_ns))
      << " s)";
    return o.str();
  }

  // What was last heard from a participant: its last heartbeat (one every kBeat seconds; a
  // participant that died within its first kBeat sent none) and its last answered step (a
  // heartbeat may be older than the last reply and name an earlier step).
  std::string last_beat_text(const Peer& peer) const {
    std::ostringstream o;
    o.precision(3);
    if (!peer.beat)
      o << "no heartbeat received (one is sent every " << kBeat << " s)";
    else
      o << "last heartbeat " << seconds_since(peer.beat_at) << " s ago ("
        << (peer.beat->state == heartbeat_t::BUSY ? "busy with step " : "idle after step ")
        << peer.beat->step_index << ")";
    if (peer.replied_step)
      o << ", last reply " << seconds_since(peer.replied_at) << " s ago (step " << *peer.replied_step
        << ")";
    else
      o << ", no reply to any step";
    return o.str();
  }

  LinkError stopped_answering(const std::string& name, const Pending& p, const LinkSettings& s) const {
    std::ostringstream msg;
    msg.precision(3);
    msg << "participant '" << name << "' stopped answering: nothing heard from it (no heartbeat, no "
        << "reply) for " << s.timeout_s << " s, its liveness timeout, while waiting for "
        << step_text(p) << " (sent " << p.request.attempt + 1 << " times); "
        << last_beat_text(peers_.at(name)) << ". Check that the process runs and reaches bus " << url_
        << "; raise participants." << name << ".timeout if it can be unreachable for longer";
    return LinkError(name, msg.str());
  }

  LinkError not_answering(const std::string& name, const Pending& p, const LinkSettings& s) const {
    std::ostringstream msg;
    msg.precision(3);
    msg << "participant '" << name << "' stopped answering: it is alive ("
        << last_beat_text(peers_.at(name)) << ") but neither answered " << step_text(p)
        << " nor reported working on it for " << (s.retries + 1) * s.timeout_s
        << " s ((retries + 1) x timeout), although the request was sent " << p.request.attempt + 1
        << " times. Its replies may not get through (a reply larger than one datagram is lost "
        << "when any of its fragments is: raise recv_buf_size in the bus URL and "
        << "net.core.rmem_max); raise participants." << name << ".retries to wait longer";
    return LinkError(name, msg.str());
  }

  void send(Pending& p) {
    const auto key = std::make_pair(p.request.participant, p.request.step_index);
    if (faults_.drop_request.count(key)) {
      faults_.drop_request.erase(key);  // lost once, like a dropped datagram
      ++stats_.dropped_by_plan;
      return;
    }
    const int copies = std::max(1, links_.at(p.request.participant).copies);
    for (int i = 0; i < copies; ++i)
      bus_.publish(channel::request(session_, p.request.participant), session_, p.request);
    stats_.redundant_copies += static_cast<uint64_t>(copies - 1);
  }

  // Handles messages for up to `ms`, publishes the master's heartbeat, checks liveness.
  void pump(int ms) {
    if (seconds_since(last_beat_) > 0.25) {
      heartbeat_t h{};
      h.session_id = session_;
      h.sender = "master";
      h.state = heartbeat_t::BUSY;
      bus_.publish(channel::heartbeat(session_), session_, h);
      last_beat_ = Clock::now();
    }
    const int r = lcm_.handleTimeout(ms);
    if (r < 0 && errno != EINTR)
      throw LinkError("", "the bus failed (lcm handle returned " + std::to_string(r) + ": " +
                              std::strerror(errno) + ")");
    stats_.auth = bus_.stats();
    if (fatal_) throw *fatal_;
    if (liveness_) liveness_();
  }

  static std::string describe_instance(const std::string& name, const std::string& host,
                                       int32_t pid) {
    return "'" + name + "' pid " + std::to_string(pid) + " on " + (host.empty() ? "?" : host);
  }
  static std::string describe_instance(const announce_t& a) {
    return describe_instance(a.participant, a.host, a.pid);
  }

  // For the connect timeout: the participants not connected that were heard only through
  // announces this master cannot accept, and the fix.
  std::string unauthenticated_text(const std::vector<configure_t>& configs,
                                   const std::map<std::string, ParticipantInfo>& connected) const {
    std::string list;
    bool sealed = false;
    for (const auto& c : configs) {
      if (connected.count(c.participant)) continue;
      auto it = refused_.find(c.participant);
      if (it == refused_.end()) continue;
      for (const auto& [id, r] : it->second) {
        sealed = sealed || r.heard == SealedBus::Heard::unreadable;
        list += (list.empty() ? "" : ", ") + describe_instance(r.announce) +
                (r.heard == SealedBus::Heard::forged      ? " (sealed with another key)"
                 : r.heard == SealedBus::Heard::unreadable ? " (sealed with a key)"
                                                           : " (no key)");
      }
    }
    if (list.empty()) return "";
    if (bus_.keyed())
      return "this master heard only unauthenticated participants, which it ignores: " + list +
             ". This master has a key ($COSIM_KEY_FILE or $COSIM_KEY) and a participant joins "
             "only with the same key: give every participant the run's key (docs/security.md)";
    return "this master heard only participants that seal their messages with a key, which it "
           "cannot check: " + list + ". This master has no key: give it theirs ($COSIM_KEY_FILE or "
           "$COSIM_KEY), or start them without one (docs/security.md)";
  }

  // Picks the free instance of a participant started by hand, once the announces have had
  // time to show every free instance; two of them is an error naming both.
  void choose(const std::string& name) {
    auto it = seen_.find(name);
    if (it == seen_.end()) return;
    const auto now = Clock::now();
    std::vector<const Seen*> free;
    for (const auto& [id, a] : it->second) {
      if (taken_.count(id) || a.announce.protocol_version != kProtocolVersion ||
          a.announce.bound_session_id != 0 || seconds_between(a.last, now) > 1.0 ||
          (a.announce.reserved_session_id != 0 && a.announce.reserved_session_id != session_))
        continue;
      free.push_back(&a);
    }
    if (free.empty()) return;
    Clock::time_point first = free.front()->first;
    for (const Seen* a : free) first = std::min(first, a->first);
    if (seconds_between(first, now) < kSettle) return;  // let a second instance show itself
    if (free.size() > 1) {
      std::string all;
      for (std::size_t i = 0; i < free.size(); ++i)
        all += (i == 0 ? "" : i + 1 == free.size() ? " and " : ", ") + describe_instance(free[i]->announce);
      throw LinkError(name, "two free participants answer to the name '" + name + "' on bus " + url_ +
                                ": " + all + "; the master cannot tell which one this run is for. "
                                "Stop all but one, give them distinct --name values, or start each "
                                "with --session for its run");
    }
    chosen_[name] = free.front()->announce.instance_id;
  }

  void on_announce(const lcm::ReceiveBuffer* rbuf, const std::string& ch) {
    announce_t m;
    const auto heard = bus_.open(rbuf, ch, {0}, m);  // announces come before any session
    if (heard == SealedBus::Heard::malformed || heard == SealedBus::Heard::forged ||
        heard == SealedBus::Heard::unreadable) {
      // Not authentic (or, without a key, sealed): never a candidate, but named when the
      // run cannot start (what it claims is all there is to go by).
      // (A few per name: a flood of forged announces must not grow this without bound.)
      if (links_.count(m.participant) && m.instance_id != 0) {
        auto& of_name = refused_[m.participant];
        if (of_name.size() < 8 || of_name.count(m.instance_id)) of_name[m.instance_id] = {m, heard};
      }
      return;
    }
    if (heard != SealedBus::Heard::ok) return;
    const announce_t* a = &m;
    if (!links_.count(a->participant) || a->instance_id == 0) return;
    const auto now = Clock::now();
    auto [it, added] = seen_[a->participant].try_emplace(a->instance_id);
    if (added) it->second.first = now;
    it->second.last = now;
    it->second.announce = *a;
  }

  // The instance that answers to `name` in this session; a second one is an error.
  void check_instance(const std::string& name, int64_t instance, const std::string& host, int32_t pid) {
    auto [it, added] = bound_.try_emplace(name, Bound{instance, host, pid});
    if (added || it->second.instance == instance || fatal_) return;
    fatal_ = LinkError(name, "two participants answer to the name '" + name + "' in session " +
                                 id_hex(session_) + ": " +
                                 describe_instance(name, it->second.host, it->second.pid) + " and " +
                                 describe_instance(name, host, pid) +
                                 "; stop the one that does not belong to this run");
  }

  void on_ready(const lcm::ReceiveBuffer* rbuf, const std::string& ch) {
    ready_t m;
    if (bus_.open(rbuf, ch, {session_}, m) != SealedBus::Heard::ok) return;
    const ready_t* r = &m;
    if (r->session_id != session_ || !peers_.count(r->participant)) return;
    if (!r->ok && r->bound_session_id != 0) {  // another run took it first: choose again
      taken_.insert(r->instance_id);
      if (chosen_.count(r->participant) && chosen_[r->participant] == r->instance_id)
        chosen_.erase(r->participant);
      std::cerr << program_ << ": " << r->error << "\n";
      return;
    }
    if (r->ok) check_instance(r->participant, r->instance_id, r->host, r->pid);
    peers_[r->participant].heard = Clock::now();
    ready_.emplace(r->participant, *r);
  }
  void on_heartbeat(const lcm::ReceiveBuffer* rbuf, const std::string& ch) {
    heartbeat_t m;
    if (bus_.open(rbuf, ch, {session_}, m) != SealedBus::Heard::ok) return;
    const heartbeat_t* h = &m;
    if (h->session_id != session_) return;
    auto it = peers_.find(h->sender);
    if (it == peers_.end()) return;
    check_instance(h->sender, h->instance_id, h->host, h->pid);
    const auto now = Clock::now();
    Peer& peer = it->second;
    peer.heard = now;
    peer.beat = *h;
    peer.beat_at = now;
    auto p = pending_.find(h->sender);
    if (p == pending_.end() || p->second.reply) return;
    Pending& q = p->second;
    const bool ours = h->step_index == q.request.step_index && h->iteration == q.request.iteration;
    if (!ours) return;
    if (h->state == heartbeat_t::BUSY) {
      q.busy = q.progress = now;  // it has the request and works on it: no resend needed
    } else if (seconds_between(q.sent, now) > peer.timer.base()) {
      q.reply_lost = true;  // done, but its reply did not arrive: ask again for the cached one
    }
  }
  void on_reply(const lcm::ReceiveBuffer* rbuf, const std::string& ch) {
    step_reply_t m;
    if (bus_.open(rbuf, ch, {session_}, m) != SealedBus::Heard::ok) return;
    const step_reply_t* r = &m;
    if (r->session_id == session_ && peers_.count(r->participant)) {
      peers_[r->participant].heard = Clock::now();
      auto b = bound_.find(r->participant);
      if (b != bound_.end() && b->second.instance != r->instance_id)
        check_instance(r->participant, r->instance_id, "?", 0);
    }
    auto it = pending_.find(r->participant);
    if (r->session_id != session_ || it == pending_.end() || it->second.reply ||
        r->step_index != it->second.request.step_index ||
        r->iteration != it->second.request.iteration) {
      ++stats_.ignored_replies;
      return;
    }
    const auto key = std::make_pair(r->participant, r->step_index);
    if (faults_.drop_reply.count(key)) {  // lost once: every copy of this answer
      faults_.drop_reply.erase(key);
      ++stats_.dropped_by_plan;
      dropping_[r->participant] = {r->step_index, r->iteration, r->attempt};
      return;
    }
    if (auto d = dropping_.find(r->participant);
        d != dropping_.end() && d->second == std::make_tuple(r->step_index, r->iteration, r->attempt))
      return;
    Pending& p = it->second;
    p.round_trip = seconds_since(p.sent);
    // Karn's rule: a reply to a request sent more than once may answer any copy.
    if (p.request.attempt == 0)
      peers_[r->participant].timer.sample(p.round_trip, std::isfinite(r->compute_seconds) ? r->compute_seconds : 0);
    p.reply = *r;
    Peer& peer = peers_[r->participant];
    peer.replied_step = r->step_index;
    peer.replied_at = Clock::now();
  }

  std::string url_;
  lcm::LCM lcm_;
  int64_t session_;
  std::map<std::string, LinkSettings> links_;
  std::string program_;  // names this side in its messages (cosim_master, dem_fmu)
  std::map<std::string, Peer> peers_;
  std::map<std::string, ready_t> ready_;
  std::map<std::string, ParticipantInfo> infos_;
  std::map<std::string, Pending> pending_;
  static constexpr double kSettle = 0.6;  // s of announces heard before a free instance is taken
  struct Seen {
    announce_t announce;
    Clock::time_point first, last;
  };
  struct Bound {
    int64_t instance;
    std::string host;
    int32_t pid;
  };
  std::map<std::string, std::map<int64_t, Seen>> seen_;  // announced instances per name
  std::map<std::string, int64_t> chosen_;                // name -> instance configured
  std::set<int64_t> taken_;                              // instances another run took
  std::map<std::string, Bound> bound_;                   // name -> instance in this session
  std::optional<LinkError> fatal_;                       // found in a handler, thrown by pump
  // A reply the fault plan loses, by participant: (step, iteration, attempt) of all its copies.
  std::map<std::string, std::tuple<int64_t, int32_t, int32_t>> dropping_;
  SealedBus bus_;                                        // seals and opens (with a key)
  struct Refused {
    announce_t announce;  // what it claims: not authentic
    SealedBus::Heard heard;
  };
  std::map<std::string, std::map<int64_t, Refused>> refused_;  // unauthenticated announces
  Clock::time_point exchange_start_ = Clock::now();
  Clock::time_point last_beat_ = Clock::now() - std::chrono::hours(1);
};

}  // namespace

std::unique_ptr<Transport> make_lcm_transport(const std::string& url, int64_t session,
                                              std::map<std::string, LinkSettings> links,
                                              std::optional<auth::Key> key,
                                              const std::string& program) {
  return std::make_unique<LcmTransport>(url, session, std::move(links), std::move(key), program);
}

}  // namespace cosim
